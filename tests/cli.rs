//! The `tcpf` binary as a user runs it: exit codes, error messages, the run directory.

use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

mod common;
use common::{
    commit_of, config, credential, credentialed, exited, fleet, free_endpoint, kill, paper, scratch, tcpf, text, Reaper,
};

#[test]
fn plan_json_has_the_contract_fields() {
    let o = tcpf(&["plan", &paper("a-nominal"), "--json"]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!((v["t_f"].as_f64().unwrap() - 45.689).abs() < 0.005);
    assert!(v["cost"].as_f64().is_some() && v["min_separation"].as_f64().is_some());
    for vehicle in v["vehicles"].as_array().unwrap() {
        for key in ["id", "cost", "min_speed", "max_speed", "max_accel"] {
            assert!(!vehicle[key].is_null(), "vehicle lacks {key}");
        }
    }
}

#[test]
fn plan_table_names_the_active_constraint() {
    let o = tcpf(&["plan", &paper("a-nominal"), "--set", "planner.a_max=0.07"]);
    assert!(o.status.success(), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("t_f = 50.1"), "{out}");
    assert!(out.contains("active constraint: a_max"), "{out}");
}

#[test]
fn typo_in_a_mission_file_exits_2_naming_file_line_and_key() {
    let dir = scratch("typo");
    let file = dir.join("typo.toml");
    let original = std::fs::read_to_string(paper("b-current")).unwrap();
    std::fs::write(&file, original.replace("kc = 0.5", "kc_gain = 0.5")).unwrap();
    let line = original.lines().position(|l| l.starts_with("kc = ")).unwrap() + 1;
    let o = tcpf(&[
        "run",
        file.to_str().unwrap(),
        "--in-process",
        "--out",
        dir.join("run").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&format!("typo.toml:{line}: key `control.kc_gain`")),
        "{err}"
    );
    assert!(!dir.join("run").exists(), "nothing written for bad input");
}

#[test]
fn missing_file_and_bad_override_exit_2() {
    let o = tcpf(&["plan", "/nonexistent/mission.toml"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("/nonexistent/mission.toml"));
    let o = tcpf(&["plan", &paper("a-nominal"), "--set", "comms.loss=2"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("comms.loss"), "{}", text(&o));
}

/// An open endpoint for ROS 2 nodes that come with no credential is refused, before a run
/// directory is made, where it cannot be what it says: without ROS 2, off TCP, already taken.
#[test]
fn ros2_open_where_it_cannot_be_exits_2_saying_why() {
    let dir = scratch("ros2-open");
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let taken = format!("tcp/{}", taken.local_addr().unwrap());
    let mission = paper("b-current");
    for (extra, why) in [
        (vec!["--ros2-open"], "the run speaks no ROS 2"),
        (
            vec!["--ros2", "--ros2-open", "udp/127.0.0.1:7447"],
            "give tcp/HOST:PORT",
        ),
        (vec!["--ros2", "--ros2-open", &taken], "cannot listen there"),
        (
            vec!["--ros2", "--ros2-open", "--links", "passwords"],
            "--links certificates",
        ),
    ] {
        let out = dir.join("run");
        let mut args = vec!["run", &mission, "--out", out.to_str().unwrap()];
        args.extend(&extra);
        let o = tcpf(&args);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {}", text(&o));
        assert!(text(&o).contains(why), "{extra:?}: {}", text(&o));
        assert!(!out.exists(), "{extra:?}: a run directory for bad input");
    }
}

#[test]
fn infeasible_plan_exits_1_with_the_binding_constraint() {
    let o = tcpf(&["plan", &paper("a-nominal"), "--set", "planner.clearance=5"]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("vehicles 1 and 2 come within") && err.contains("clearance 5"),
        "{err}"
    );
}

fn run_in_process(case: &str, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["run", case, "--in-process", "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    tcpf(&args)
}

#[test]
fn run_writes_the_run_directory() {
    let dir = scratch("rundir");
    let o = run_in_process(&paper("b-current"), &dir, &[]);
    assert!(o.status.success(), "{}", text(&o));
    for f in ["mission.toml", "plan.json", "telemetry.csv", "summary.json"] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["mission"], "paper-b-current");
    assert_eq!(s["mode"], "in-process");
    assert_eq!(s["clock"], "lockstep");
    let ticks = s["ticks"].as_u64().unwrap();
    for v in s["vehicles"].as_array().unwrap() {
        assert!((v["arrival_time"].as_f64().unwrap() - 55.46).abs() < 0.1);
        assert_eq!(v["lost"], false);
    }
    for key in [
        "max_coordination_error",
        "min_clearance",
        "max_coordination_error_to_last_arrival",
        "min_clearance_to_last_arrival",
        "wall_time_s",
    ] {
        assert!(s[key].as_f64().is_some(), "{key}");
    }
    assert_eq!(s["links"].as_array().unwrap().len(), 2);
    let rows = std::fs::read_to_string(dir.join("telemetry.csv"))
        .unwrap()
        .lines()
        .count() as u64;
    assert_eq!(rows, 1 + 2 * ticks, "header plus one row per vehicle per tick");
    // The resolved mission is itself a valid mission file.
    let o = tcpf(&["plan", dir.join("mission.toml").to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
}

#[test]
fn an_out_given_as_a_new_directory_and_a_dot_is_that_directory() {
    let dir = scratch("out-dot");
    let o = run_in_process(&paper("a-nominal"), &dir.join("new").join("."), &[]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(dir.join("new/summary.json").is_file());
    let o = a_small_sweep(&dir.join("sweep").join("."));
    assert!(o.status.success(), "{}", text(&o));
    assert!(dir.join("sweep/runs.csv").is_file());
}

/// Case (a) swept over one loss and one seed, in-process, into `out`.
fn a_small_sweep(out: &Path) -> Output {
    let args = ["--loss", "0", "--seeds", "1", "--out", out.to_str().unwrap()];
    tcpf(&[&["sweep", &paper("a-nominal")], &args[..]].concat())
}

/// Runs started at once each write a directory of their own: without `--out`, each its own
/// `runs/…` (the same second, the same name); given the same `--out`, one runs and the other is
/// refused, never writing its files among the first's.
#[test]
fn runs_started_at_once_never_share_a_run_directory() {
    let dir = scratch("at-once");
    let seed_of = |run: &Path| -> String {
        let mission = std::fs::read_to_string(run.join("mission.toml")).unwrap();
        let seed = mission.lines().find(|l| l.starts_with("seed")).unwrap();
        seed.rsplit(' ').next().unwrap().to_string()
    };
    for round in 0..5 {
        let cwd = dir.join(format!("default{round}"));
        std::fs::create_dir_all(&cwd).unwrap();
        let runs: Vec<_> = (1..=3)
            .map(|seed| {
                std::process::Command::new(env!("CARGO_BIN_EXE_tcpf"))
                    .args(["run", &paper("a-nominal"), "--in-process", "--seed", &seed.to_string()])
                    .current_dir(&cwd)
                    .stdout(std::process::Stdio::piped())
                    .stderr(std::process::Stdio::piped())
                    .spawn()
                    .unwrap()
            })
            .collect();
        for run in runs {
            let o = run.wait_with_output().unwrap();
            assert!(o.status.success(), "{}", text(&o));
        }
        let made: Vec<_> = std::fs::read_dir(cwd.join("runs"))
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .collect();
        assert_eq!(made.len(), 3, "{made:?}");
        let mut seeds: Vec<String> = made.iter().map(|run| seed_of(run)).collect();
        seeds.sort();
        assert_eq!(seeds, ["1", "2", "3"], "each run's own mission, in its own directory");

        let out = dir.join(format!("same{round}"));
        let spawn = |seed: &str| {
            std::process::Command::new(env!("CARGO_BIN_EXE_tcpf"))
                .args(["run", &paper("a-nominal"), "--in-process", "--seed", seed])
                .args(["--out", out.to_str().unwrap()])
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        };
        let (first, second) = (spawn("1"), spawn("2"));
        let codes = [first.wait_with_output().unwrap(), second.wait_with_output().unwrap()];
        let won: Vec<usize> = (0..2).filter(|&k| codes[k].status.success()).collect();
        assert_eq!(won.len(), 1, "{:?}", codes.iter().map(text).collect::<Vec<_>>());
        let lost = &codes[1 - won[0]];
        assert_eq!(lost.status.code(), Some(2), "{}", text(lost));
        assert_eq!(
            seed_of(&out),
            (won[0] + 1).to_string(),
            "the run that ran owns the directory"
        );
    }
}

/// A law whose commands are not finite (d1 so small that it overflows) loses both vehicles
/// in-process as over Zenoh, where the world refuses such a command as it decodes it, and says
/// why: the refusals are counted as the processes count them.
#[test]
fn an_in_process_run_counts_the_commands_it_refused() {
    let out = scratch("refused-in-process");
    let o = run_in_process(&paper("a-nominal"), &out, &["--set", "control.d1=1e-300"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("refused messages: 2 (2 non_finite)"), "{}", text(&o));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["rejected_messages"], 2, "{s}");
    assert_eq!(s["rejections"]["non_finite"], 2, "{s}");
    assert_eq!(s["vehicles"][0]["lost_reason"], "silent", "{s}");
}

/// A disk that fills up while a run writes (a tmpfs of 300 kB, which long3's telemetry
/// outgrows) fails the run naming the file it could not write.
#[test]
fn a_run_on_a_full_disk_names_the_file_it_could_not_write() {
    struct Mounted(std::path::PathBuf);
    impl Drop for Mounted {
        fn drop(&mut self) {
            let _ = std::process::Command::new("umount").arg(&self.0).status();
        }
    }
    let small = scratch("full-disk");
    let mounted = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=300k", "tmpfs"])
        .arg(&small)
        .status()
        .unwrap();
    assert!(
        mounted.success(),
        "mount a tmpfs (the tests run as root, as .ci/run does)"
    );
    let _mounted = Mounted(small.clone());
    let out = small.join("r");
    let o = tcpf(&["run", &config("long3"), "--in-process", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let said = text(&o);
    let named = ["telemetry.csv", "messages.csv", "run.mcap", "summary.json"]
        .iter()
        .any(|f| said.contains(&format!("error: cannot write {}", out.join(f).display())));
    assert!(named && said.contains("No space left on device"), "{said}");
    // A summary nonetheless, whole, that says the run did not finish (it was left empty, or
    // missing in-process).
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["completed"], false);
    assert!(
        summary["failure"]
            .as_str()
            .unwrap()
            .starts_with("the run stopped before tcpf wrote its summary"),
        "{summary}"
    );
}

#[test]
fn same_mission_and_seed_give_byte_identical_telemetry() {
    let dir = scratch("identical");
    let (a, b, c) = (dir.join("a"), dir.join("b"), dir.join("c"));
    for (out, seed) in [(&a, "3"), (&b, "3"), (&c, "4")] {
        let o = run_in_process(&paper("d-lossy"), out, &["--seed", seed]);
        assert!(o.status.success(), "{}", text(&o));
    }
    let read = |d: &Path| std::fs::read(d.join("telemetry.csv")).unwrap();
    assert!(read(&a) == read(&b), "same seed, same bytes");
    assert!(read(&a) != read(&c), "another seed, another run");
}

#[test]
fn a_run_that_does_not_finish_exits_1() {
    let dir = scratch("short");
    let o = run_in_process(&paper("b-current"), &dir, &["--set", "mission.max_duration=10"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["completed"], false);
    assert!(s["vehicles"][0]["arrival_time"].is_null());
    assert!(
        text(&o).contains("NOT completed: vehicles 1, 2 not arrived by the run's last tick"),
        "{}",
        text(&o)
    );
}

/// `tcpf gen lanes … | head -1`: the reader goes away, and the writer stops without a word; a
/// stdout that cannot be written for another reason fails the command.
#[test]
fn output_to_a_reader_that_left_ends_quietly_and_to_a_full_disk_fails() {
    use std::io::{BufRead, BufReader};
    use std::process::{Command, Stdio};
    let mut gen = Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args(["gen", "lanes", "--vehicles", "1000"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(gen.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.starts_with("# 1000 vehicles"), "{first}");
    let o = gen.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(o.stderr.is_empty(), "{}", text(&o));
    let full = Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args(["gen", "lanes", "--vehicles", "3"])
        .stdout(std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap())
        .output()
        .unwrap();
    assert_eq!(full.status.code(), Some(1), "{}", text(&full));
    assert!(
        text(&full).contains("writing to stdout: No space left"),
        "{}",
        text(&full)
    );
}

#[test]
fn a_generated_fleet_of_ten_plans_and_arrives() {
    let dir = scratch("gen");
    let o = tcpf(&["gen", "lanes", "--vehicles", "10"]);
    assert!(o.status.success(), "{}", text(&o));
    let file = dir.join("lanes10.toml");
    std::fs::write(&file, &o.stdout).unwrap();
    let out = dir.join("run");
    let o = tcpf(&[
        "run",
        file.to_str().unwrap(),
        "--in-process",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let vehicles = s["vehicles"].as_array().unwrap();
    assert_eq!(vehicles.len(), 10);
    assert!(vehicles.iter().all(|v| v["arrival_time"].is_f64()), "{s}");
    assert_eq!(
        s["links"].as_array().unwrap().len(),
        20,
        "a ring of ten: both ways on ten edges"
    );
}

#[test]
fn command_line_misuse_exits_2_with_a_clear_message() {
    let mission = paper("b-current");
    let dir = scratch("misuse");
    let file = dir.join("a-file");
    std::fs::write(&file, "not a directory").unwrap();
    let under_file = file.join("run");
    let full = dir.join("full");
    std::fs::create_dir_all(&full).unwrap();
    std::fs::write(full.join("telemetry.csv"), "another run's").unwrap();
    let bad_config = dir.join("zenoh.json5");
    std::fs::write(&bad_config, "{ mode: \"client\", bogus: 1 }").unwrap();
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let taken = taken.local_addr().unwrap().to_string();
    let busy_out = dir.join("busy");
    let unrecorded = dir.join("unrecorded");
    let portless = dir.join("portless.json5");
    std::fs::write(&portless, "{ listen: { endpoints: { router: [\"tcp/127.0.0.1\"] } } }").unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["agent", &mission, "--id", "1", "--stale-timeout", "-1"],
            "(0, 86400]",
        ),
        (
            vec!["agent", &mission, "--id", "1", "--stale-timeout", "NaN"],
            "(0, 86400]",
        ),
        (
            vec!["agent", &mission, "--id", "1", "--startup-timeout", "inf"],
            "(0, 86400]",
        ),
        (
            vec!["agent", &mission, "--id", "1", "--stale-timeout", "1e300"],
            "(0, 86400]",
        ),
        (
            vec!["world", &mission, "--startup-timeout", "soon"],
            "not a number of seconds",
        ),
        (vec!["bench", &mission, "--count", "0"], "--count"),
        (vec!["sweep", &mission, "--loss", "0,0.5", "--seeds", "0"], "--seeds"),
        (vec!["sweep", &mission, "--seeds", "1"], "--loss <LOSS>|--param"),
        (
            vec!["sweep", &mission, "--loss", "0", "--seeds", "9223372036854775808"],
            "--seeds",
        ),
        (
            vec!["sweep", &mission, "--param", "comms.nonsense=1,2", "--seeds", "1"],
            "comms.nonsense",
        ),
        (
            vec!["run", &mission, "--in-process", "--out", file.to_str().unwrap()],
            "is a file",
        ),
        (
            vec!["run", &mission, "--in-process", "--out", full.to_str().unwrap()],
            "already holds files",
        ),
        (
            vec!["run", &mission, "--in-process", "--out", under_file.to_str().unwrap()],
            "--out: cannot create run directory",
        ),
        (
            vec![
                "sweep",
                &mission,
                "--loss",
                "0",
                "--seeds",
                "1",
                "--out",
                under_file.to_str().unwrap(),
            ],
            "cannot write the sweep there",
        ),
        (
            vec![
                "sweep",
                &mission,
                "--loss",
                "0",
                "--seeds",
                "1",
                "--out",
                full.to_str().unwrap(),
            ],
            "already holds files",
        ),
        (
            vec!["run", &mission, "--in-process", "--seed", "18446744073709551615"],
            "--seed",
        ),
        (vec!["agent", &mission, "--id", "9"], "--id 9"),
        (
            vec!["run", &mission, "--command-timeout", "2"],
            "must exceed the agents' stale timeout",
        ),
        (
            vec!["plan", &mission, "--set", "vehicle.7.weight=2"],
            "no vehicle with id 7",
        ),
        (vec!["plan", &mission, "--set", "vehicle.1.colour=2"], "colour"),
        (vec!["gen", "lanes", "--vehicles", "1"], "2..=1000"),
        (vec!["gen", "lanes", "--vehicles", "3", "--loss", "1.5"], "[0, 1]"),
        (
            vec!["sweep", &mission, "--loss", "0.5,0.5", "--seeds", "1"],
            "swept twice",
        ),
        (
            vec![
                "sweep",
                &mission,
                "--loss",
                "0",
                "--seeds",
                "1",
                "--set",
                "mission.seed=9",
            ],
            "the sweep gives each run its seed",
        ),
        (
            vec!["sweep", &mission, "--loss", "0,0.5", "--seeds", "9223372036854775807"],
            "more runs than a sweep counts",
        ),
        (
            vec!["bench", &mission, "--set", "mission.clock=realtime"],
            "tcpf bench measures a lockstep fleet",
        ),
        (
            vec!["sweep", &mission, "--loss", "0,0.0", "--seeds", "1"],
            "the value 0.0 is swept twice (0 and 0.0)",
        ),
        (
            vec![
                "sweep",
                &mission,
                "--param",
                "vehicle.1.start=[0,0],[0,1",
                "--seeds",
                "1",
            ],
            "vehicle.1.start=[0,0],[0,1: a quote, bracket or brace is left open",
        ),
        (
            vec!["run", &mission, "--clock", "realtime", "--time-scale", "0"],
            "'--time-scale <X>'",
        ),
        (
            vec!["run", &mission, "--in-process", "--time-scale", "5"],
            "applies to the realtime clock only",
        ),
        (
            vec![
                "sweep",
                &mission,
                "--loss",
                "0",
                "--seeds",
                "1",
                "--set",
                "mission.clock=realtime",
            ],
            "an in-process sweep runs lockstep only",
        ),
        (
            vec![
                "sweep",
                &mission,
                "--param",
                "mission.clock=lockstep,realtime",
                "--seeds",
                "1",
            ],
            "an in-process sweep runs lockstep only",
        ),
        (
            vec!["run", &mission, "--in-process", "--time-scale", "5"],
            "(from --time-scale 5)",
        ),
        // 2^64 − 1 recorders, plus the launcher's own, wrapped to none: the run started at once.
        (
            vec!["run", &mission, "--recorders", "18446744073709551615"],
            "is not in 0..=63",
        ),
        // 64 more and the launcher's own: 65, more than a world waits for.
        (vec!["run", &mission, "--recorders", "64"], "is not in 0..=63"),
        (vec!["world", &mission, "--recorders", "65"], "is not in 0..=64"),
        // A seed is a TOML integer: a sweep's last one is a seed `tcpf run --seed` takes.
        (
            vec![
                "sweep",
                &mission,
                "--loss",
                "0",
                "--seeds",
                "2",
                "--seed-start",
                "9223372036854775807",
            ],
            "the last seed is past 9223372036854775807 (2^63 − 1)",
        ),
        // ROS 2's domains are 0 to 232; an in-process run has no bus to speak it on.
        (vec!["world", &mission, "--ros2", "233"], "is not in 0..=232"),
        (
            vec!["run", &mission, "--in-process", "--ros2"],
            "'--in-process' cannot be used with '--ros2 [<DOMAIN>]'",
        ),
        // Every role took 1e-22 and panicked on a wall-clock period no computer can wait.
        (
            vec!["run", &mission, "--clock", "realtime", "--time-scale", "1e-22"],
            "in [0.001, 1000]",
        ),
        // What followed the newline was parsed as part of the file, then dropped in silence.
        (
            vec!["plan", &mission, "--set", "mission.seed=5\n[planner]\ntf_min=40"],
            "a value is one line",
        ),
        (
            vec!["run", &mission, "--in-process", "--recorders", "1"],
            "the argument '--in-process' cannot be used with '--recorders <N>'",
        ),
        (
            vec!["run", &mission, "--in-process", "--restart", "on-failure"],
            "the argument '--in-process' cannot be used with '--restart <RESTART>'",
        ),
        (
            vec!["sweep", &mission, "--param", "mission.seed=1,2", "--seeds", "1"],
            "the sweep gives each run its seed",
        ),
        (
            vec![
                "sweep",
                &mission,
                "--loss",
                "0",
                "--set",
                "comms.loss=0.5",
                "--seeds",
                "1",
            ],
            "comms.loss is a key the sweep sets",
        ),
        (
            vec!["sweep", &mission, "--loss", "0,,0.5", "--seeds", "1"],
            "comms.loss: an empty value in 0,,0.5",
        ),
        (
            vec!["run", &mission, "--in-process", "--command-timeout", "5"],
            "the argument '--in-process' cannot be used with '--command-timeout <COMMAND_TIMEOUT>'",
        ),
        (
            vec!["run", &mission, "--in-process", "--startup-timeout", "5"],
            "the argument '--in-process' cannot be used with '--startup-timeout <STARTUP_TIMEOUT>'",
        ),
        // Zenoh options that cannot work are bad input too, said without Zenoh's source paths.
        (
            vec!["planner", &mission, "-e", "foo"],
            "--connect foo: an endpoint is <protocol>/<address>",
        ),
        (
            vec!["agent", &mission, "--id", "1", "-l", "tcp/127.0.0.1:99999"],
            "--listen tcp/127.0.0.1:99999: the address needs a port",
        ),
        (vec!["router", "-e", "tcp/127.0.0.1"], "the address needs a port"),
        (
            vec!["world", &mission, "--mode", "bogus"],
            "--mode bogus: expected peer",
        ),
        (
            vec![
                "record",
                &mission,
                "-c",
                bad_config.to_str().unwrap(),
                "--out",
                unrecorded.to_str().unwrap(),
            ],
            "bad Zenoh config: line 1, column 19: unknown field `bogus`",
        ),
        (
            vec!["planner", &mission, "-c", "/nonexistent/zenoh.json5"],
            "/nonexistent/zenoh.json5: bad Zenoh config",
        ),
        (
            vec!["router", "-c", portless.to_str().unwrap()],
            "portless.json5: listen/endpoints tcp/127.0.0.1: the address needs a port",
        ),
        (vec!["planner", &mission, "-e", "tcp/::1"], "an IPv6 host in brackets"),
        // A file key wrong beside the overrides names them, each as it was typed.
        (
            vec![
                "run",
                &mission,
                "--in-process",
                "--seed",
                "3",
                "--set",
                "planner.tf_min=70",
            ],
            "(with --set planner.tf_min=70, --seed 3)",
        ),
        (
            vec![
                "run",
                &mission,
                "--in-process",
                "--live",
                &taken,
                "--out",
                busy_out.to_str().unwrap(),
            ],
            "cannot serve the live view there",
        ),
    ];
    for (args, says) in cases {
        let o = tcpf(&args);
        let out = text(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {out}");
        assert!(out.contains(says), "{args:?} should say {says:?}: {out}");
        assert!(
            !out.contains("panicked") && !out.contains(".cargo/registry"),
            "{args:?}: {out}"
        );
    }
    assert_eq!(
        std::fs::read_to_string(full.join("telemetry.csv")).unwrap(),
        "another run's",
        "nothing was overwritten"
    );
    assert!(
        !busy_out.exists(),
        "a run that cannot serve its live view leaves no directory"
    );
    assert!(
        !unrecorded.exists(),
        "a recorder with bad Zenoh options leaves no directory to be in the way of the next"
    );
}

/// Ctrl-C, or the terminal closing (SIGHUP), stops an in-process run with its summary and
/// report of whole ticks.
#[test]
fn sigint_or_sighup_on_an_in_process_run_exits_130_with_summary_and_report() {
    for signal in ["-INT", "-HUP"] {
        interrupt_an_in_process_run(signal);
    }
}

/// Started under `nohup`, a run goes on when the terminal closes (SIGHUP), as asked.
#[test]
fn under_nohup_a_run_ignores_sighup() {
    let out = scratch("nohup");
    let mut run = a_long_in_process_run(
        std::process::Command::new("nohup").arg(env!("CARGO_BIN_EXE_tcpf")),
        &out,
    );
    kill("-HUP", run.0.id());
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        run.0.try_wait().unwrap().is_none(),
        "SIGHUP stopped a run started under nohup"
    );
    kill("-INT", run.0.id());
    assert_eq!(run.0.wait().unwrap().code(), Some(130));
}

/// `tcpf` (behind `command`'s program) running case (b) in-process into `out`, long enough to be
/// interrupted (554 637 ticks, about 4 s here), once it has written its first ticks.
fn a_long_in_process_run(command: &mut std::process::Command, out: &Path) -> Reaper {
    let run = Reaper(
        command
            .args([
                "run",
                &paper("b-current"),
                "--in-process",
                "--out",
                out.to_str().unwrap(),
            ])
            .args(["--set", "mission.control_period=0.0001"])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap(),
    );
    let deadline = Instant::now() + Duration::from_secs(60);
    while std::fs::metadata(out.join("telemetry.csv")).map_or(0, |m| m.len()) < 100_000 {
        assert!(Instant::now() < deadline, "the run never started writing");
        std::thread::sleep(Duration::from_millis(10));
    }
    run
}

fn interrupt_an_in_process_run(signal: &str) {
    let out = scratch(&format!("in-process{signal}"));
    let mut run = a_long_in_process_run(&mut std::process::Command::new(env!("CARGO_BIN_EXE_tcpf")), &out);
    kill(signal, run.0.id());
    let status = run.0.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{signal}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["interrupted"], true);
    assert_eq!(summary["completed"], false);
    let ticks = summary["ticks"].as_u64().unwrap();
    assert!(ticks > 0 && ticks < 554_637, "stopped part-way: {ticks} ticks");
    let rows = std::fs::read_to_string(out.join("telemetry.csv"))
        .unwrap()
        .lines()
        .count() as u64;
    assert_eq!(rows, 1 + 2 * ticks, "whole ticks only");
    assert!(out.join("report.html").is_file());
    assert!(out.join("run.mcap").is_file());
}

#[test]
fn roles_waiting_at_startup_honour_sigterm_sigint_and_sighup() {
    let _fleet = fleet();
    for (args, signal) in [
        (vec!["agent", "--id", "1"], "-TERM"),
        (vec!["world"], "-TERM"),
        (vec!["agent", "--id", "1"], "-HUP"),
        (vec!["agent", "--id", "2"], "-INT"),
        (vec!["world"], "-INT"),
    ] {
        // Alone, each waits for a planner that never comes (up to --startup-timeout, 60 s).
        let mut role = Reaper(
            std::process::Command::new(env!("CARGO_BIN_EXE_tcpf"))
                .args(credentialed(
                    &[&args[..1], &[paper("b-current").as_str()], &args[1..]].concat(),
                ))
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::null())
                .spawn()
                .unwrap(),
        );
        // SIGHUP, SIGINT and SIGTERM handled: the role is under way, and waits.
        let deadline = Instant::now() + Duration::from_secs(30);
        while !catches(role.0.id(), &[1, 2, 15]) {
            assert!(role.0.try_wait().unwrap().is_none(), "{args:?} waits at startup");
            assert!(Instant::now() < deadline, "{args:?} never handled {signal}");
            std::thread::sleep(Duration::from_millis(10));
        }
        kill(signal, role.0.id());
        let deadline = Instant::now() + Duration::from_secs(2);
        let status = loop {
            if let Some(status) = role.0.try_wait().unwrap() {
                break status;
            }
            assert!(Instant::now() < deadline, "{args:?} ignored {signal} at startup");
            std::thread::sleep(Duration::from_millis(10));
        };
        assert_eq!(status.code(), Some(130), "{args:?} after {signal}");
    }
}

/// `tcpf credential FILE` writes a user and password only its owner may read, which a role takes
/// with `--credential`; it never replaces a file (every host holding it would be locked out),
/// and a credential others may read is refused, as ssh refuses such a key.
#[test]
fn a_credential_is_made_owner_only_never_overwritten_and_refused_when_others_can_read_it() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch("credential-made");
    let file = dir.join("fleet.key");
    let path = file.to_str().unwrap();
    let o = tcpf(&["credential", path]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains(&format!("--credential {path}")), "{}", text(&o));
    let made = std::fs::read_to_string(&file).unwrap();
    let (user, password) = made.trim().split_once(':').unwrap();
    assert_eq!((user, password.len()), ("tcpf", 32), "{made}");
    assert_eq!(std::fs::metadata(&file).unwrap().permissions().mode() & 0o777, 0o600);
    let o = tcpf(&["credential", path]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("exists; a credential is never overwritten"),
        "{}",
        text(&o)
    );
    assert_eq!(std::fs::read_to_string(&file).unwrap(), made, "the credential is kept");
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o644)).unwrap();
    let o = tcpf(&["planner", &paper("b-current"), "--credential", path]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains(&format!("--credential {path}: others may read it (mode 644)")),
        "{}",
        text(&o)
    );
    let o = tcpf(&["planner", &paper("b-current"), "--credential", path, "--open"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("cannot be used with"), "{}", text(&o));
    // The file is every listener's dictionary too: a second line would be a second user.
    let two = dir.join("two.key");
    std::fs::write(&two, format!("{}mallory:open\n", made)).unwrap();
    std::fs::set_permissions(&two, std::fs::Permissions::from_mode(0o600)).unwrap();
    let o = tcpf(&["planner", &paper("b-current"), "--credential", two.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("more than one line"), "{}", text(&o));
}

/// A role started by hand demands a credential: without one it does not start (exit 2) and says
/// how to make one, unless told to run open, when it says so as it starts; a role whose
/// configuration or `--credential` demands a user and password says nothing of the kind.
#[test]
fn a_role_runs_open_only_when_told_and_says_so() {
    let _fleet = fleet();
    let dir = scratch("open");
    let o = tcpf(&["planner", &paper("b-current")]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    for words in [
        "this role would run open",
        "`tcpf credential fleet.key`",
        "--credential",
        "--open",
    ] {
        assert!(text(&o).contains(words), "{words}: {}", text(&o));
    }
    let dictionary = dir.join("credentials");
    std::fs::write(&dictionary, "tcpf:a-secret\n").unwrap();
    let closed = dir.join("closed.json5");
    std::fs::write(
        &closed,
        format!(
            r#"{{ mode: "peer", scouting: {{ multicast: {{ enabled: false }} }}, listen: {{ endpoints: ["tcp/127.0.0.1:0"] }},
               transport: {{ auth: {{ usrpwd: {{ user: "tcpf", password: "a-secret", dictionary_file: "{}" }} }} }} }}"#,
            dictionary.display()
        ),
    )
    .unwrap();
    let key = credential().to_str().unwrap();
    let closed = closed.to_str().unwrap();
    for (how, open) in [
        (["--open", ""], true),
        (["-c", closed], false),
        (["--credential", key], false),
    ] {
        let log = dir.join(format!("planner{}.log", how[0]));
        let _planner = Reaper(
            std::process::Command::new(env!("CARGO_BIN_EXE_tcpf"))
                .args(["planner", &paper("b-current")])
                .args(how.iter().filter(|a| !a.is_empty()))
                .stdout(std::process::Stdio::null())
                .stderr(std::fs::File::create(&log).unwrap())
                .spawn()
                .unwrap(),
        );
        // Serving: it has opened its session, and said what it had to before.
        common::wait_for_text(&log, "planner: t_f =", Duration::from_secs(30));
        let said = std::fs::read_to_string(&log).unwrap();
        assert_eq!(said.contains("this role runs open (--open)"), open, "{how:?}: {said}");
    }
}

/// A role that cannot listen where it was told says why: the port is taken, or the address
/// is not this host's.
#[test]
fn a_role_that_cannot_listen_says_why() {
    let _fleet = fleet();
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let busy = format!("tcp/{}", taken.local_addr().unwrap());
    for (endpoint, hint) in [
        (
            busy.as_str(),
            "Address already in use (os error 98)] (is another process listening there?)",
        ),
        // TEST-NET-1: nobody's address.
        ("tcp/192.0.2.1:7447", "(is that address one of this host's?)"),
    ] {
        let o = tcpf(&["planner", &paper("b-current"), "-l", endpoint, "--open"]);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(text(&o).contains(hint), "{}", text(&o));
    }
}

#[test]
fn a_recorder_that_never_meets_its_world_says_so_after_its_startup_timeout() {
    let _fleet = fleet();
    let dir = scratch("no-world");
    let out = dir.join("runs").join("p");
    // A router and no world: the world is of another mission, or not started yet.
    let (router, endpoint) = common::listening(|e| {
        std::process::Command::new(env!("CARGO_BIN_EXE_tcpf"))
            .args(credentialed(&["router", "-l", e]))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap()
    });
    let _router = Reaper(router);
    let mut recorder = Reaper(
        std::process::Command::new(env!("CARGO_BIN_EXE_tcpf"))
            .args(credentialed(&["record", &paper("b-current"), "--startup-timeout", "1"]))
            .args(["-e", &endpoint, "--out", out.to_str().unwrap()])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let (code, stderr) = exited(
        &mut recorder.0,
        Duration::from_secs(20),
        "the recorder still waits for a world that never comes",
    );
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("no world of mission paper-b-current within 1s"),
        "{stderr}"
    );
    // Nothing was recorded: the directories it made for --out are gone, and the corrected
    // command may take the same --out.
    let left = || std::fs::read_dir(&dir).unwrap().collect::<Vec<_>>();
    assert!(!dir.join("runs").exists(), "{:?}", left());
    // Nor when its session never opens (nothing listens there: a mistyped endpoint).
    let o = tcpf(&[
        "record",
        &paper("b-current"),
        "--mode",
        "client",
        "-e",
        &free_endpoint(),
        "--credential",
        credential().to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        text(&o).contains("nothing recorded: cannot open the Zenoh session"),
        "{}",
        text(&o)
    );
    assert!(!dir.join("runs").exists(), "{:?}", left());
}

/// `tcpf bench` prints each figure beside the baseline it is measured against, all from one
/// invocation; the figures themselves vary with the machine, their presence and sense do not.
#[test]
fn bench_prints_every_figure_beside_its_baseline() {
    let _fleet = fleet();
    let o = tcpf(&["bench", &paper("b-current"), "--count", "50", "--fleets", "3,4"]);
    assert!(o.status.success(), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    let line = |start: &str| {
        out.lines()
            .find(|l| l.starts_with(start))
            .unwrap_or_else(|| panic!("no line '{start}' in:\n{out}"))
            .to_string()
    };
    // The numbers of a line, in order.
    let numbers = |l: &str| -> Vec<f64> {
        l.split(|c: char| !(c.is_ascii_digit() || c == '.'))
            .filter_map(|w| w.trim_matches('.').parse().ok())
            .collect()
    };
    let plan = numbers(&line("plan (2 vehicles)"));
    assert!(plan[1] > 0.0 && plan[3] > 0.0, "{plan:?}");
    let fleet = numbers(&line("in-process:"));
    assert!(
        fleet[0] > 0.1 && fleet[1] > fleet[0] && fleet[3] > fleet[0],
        "the world alone, and the world with the laws alone, are faster: {fleet:?}"
    );
    // A ratio is printed to two decimals (±0.005) of figures printed to one (µs) or two: the
    // quotient of the printed figures is within that rounding, whatever the ratio's size.
    let quotient = |ratio: f64, a: f64, b: f64| (ratio - a / b).abs() <= 0.005 + 0.01 * ratio;
    // Both rates are printed to two decimals: their quotient is known to within that rounding.
    let rounding = 0.005 + fleet[4] * (0.005 / fleet[0] + 0.005 / fleet[3]);
    assert!((fleet[4] - fleet[0] / fleet[3]).abs() <= rounding, "{fleet:?}");
    // Round trips and ticks are medians taken apart from each other on a shared machine, and
    // a router on its own threads adds little to a round trip: which of them is larger varies
    // from run to run, so only their range and the printed ratios are checked.
    // The acoustic layer's cost: ticks with and without, their ratio, per frame, and its share.
    let modem = numbers(&line("in-process, 10 lanes with events on acoustic modems"));
    let [_, with, without, ratio, per_frame, frames, share] = modem[..] else {
        panic!("{modem:?}")
    };
    assert!(with > 0.0 && without > 0.0 && frames > 100.0, "{modem:?}");
    assert!((ratio - with / without).abs() <= 0.01 + 0.05 * ratio, "{modem:?}");
    assert!(per_frame >= 0.0 && share < 100.0, "{modem:?}");
    let rtt = numbers(&line("zenoh round trip"));
    assert!(
        rtt.len() == 2 && rtt.iter().all(|&t| t > 10.0 && t < 1e5),
        "round trips in µs, direct and routed: {rtt:?}"
    );
    let tick = numbers(&line("lockstep tick (2 vehicles, 5548 ticks, best of 3 runs)"));
    assert!(tick[3] > 10.0 && tick[3] < 1e5, "tick in µs: {tick:?}");
    assert!(quotient(tick[4], tick[3], rtt[0]), "{tick:?} {rtt:?}");
    assert!(quotient(tick[5], tick[3], rtt[1]), "{tick:?} {rtt:?}");
    // The tick with --ros2 and its ratio to the tick without, the line's last two numbers.
    let ros2 = numbers(&line("lockstep tick with --ros2"));
    let [with, ratio] = ros2[ros2.len() - 2..] else {
        panic!("{ros2:?}")
    };
    assert!(with > 10.0 && with < 1e5, "tick in µs: {ros2:?}");
    assert!(quotient(ratio, with, tick[3]), "{ros2:?} {tick:?}");
    // The tick with a certificate per role, with a password per role, and with neither.
    let rules = numbers(&line("lockstep tick with a certificate per role"));
    let [with, passwords, plain, ratio, ratio_passwords] = rules[rules.len() - 5..] else {
        panic!("{rules:?}")
    };
    assert!((with - tick[3]).abs() < 0.1, "the fleet's own tick: {rules:?} {tick:?}");
    assert!(
        plain > 10.0 && plain < 1e5 && passwords > 10.0 && passwords < 1e5,
        "ticks in µs: {rules:?}"
    );
    assert!(quotient(ratio, with, plain), "{rules:?}");
    assert!(quotient(ratio_passwords, passwords, plain), "{rules:?}");
    // b-current's control period is 0.01 s: a tick's wall time says how fast it runs.
    let speed = numbers(&line("simulated / wall time:"));
    assert!(
        (speed[0] - 0.01 / (tick[3] * 1e-6)).abs() < 0.01 * speed[0],
        "{speed:?} {tick:?}"
    );
    assert!(
        speed[1] > 0.0 && speed[1] < speed[0],
        "the start and the end slow the whole run: {speed:?}"
    );
    // The start-up beside the one roles started by hand pay (1.5 s of claims settling at least).
    let start = numbers(&line("start-up: the first tick"));
    let [first, settled, ratio] = start[..] else {
        panic!("{start:?}")
    };
    assert!(first > 0.0 && settled > 1.5, "{start:?}");
    assert!(quotient(ratio, first, settled), "{start:?}");
    // The fleets of `tcpf gen lanes`, each beside the direct round trip; lanes tick every 0.01 s.
    let mut lanes = Vec::new();
    for n in [3.0, 4.0] {
        let l = numbers(&line(&format!("{n} lanes as processes")));
        let [_, ticks, _, tick, per_agent, by_tick, whole, first, ratio] = l[..] else {
            panic!("{l:?}")
        };
        assert!(ticks > 1000.0 && tick > 10.0 && tick < 1e5, "{l:?}");
        assert!((per_agent - tick / n).abs() < 0.06, "{l:?}");
        assert!((by_tick - 0.01 / (tick * 1e-6)).abs() < 0.01 * by_tick, "{l:?}");
        assert!(whole > 0.0 && whole < by_tick && first > 0.0, "{l:?}");
        assert!(quotient(ratio, tick, rtt[0]), "{l:?} {rtt:?}");
        lanes.push(tick);
    }
    let scale = numbers(&line("from 3 to 4 lanes: the tick"));
    assert!(quotient(scale[2], lanes[1], lanes[0]), "{scale:?} {lanes:?}");
    let memory = numbers(&line("per agent:"));
    assert!(memory.iter().all(|&m| m > 0.5 && m < 200.0), "{memory:?}");
    // Sockets grow with the fleet, not its square: a handful per process.
    let sockets = numbers(&line("agents' sockets:"));
    assert_eq!(sockets[1], 2.0, "{sockets:?}");
    assert!(
        sockets[0] <= 8.0 * sockets[1] && sockets[2] <= 8.0 * sockets[1],
        "{sockets:?}"
    );
}

/// Whether process `pid` catches SIGINT yet.
fn catches(pid: u32, signals: &[u32]) -> bool {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("SigCgt:"))
        .and_then(|mask| u64::from_str_radix(mask.trim(), 16).ok())
        .is_some_and(|mask| signals.iter().all(|s| mask & (1 << (s - 1)) != 0))
}

/// A client of a router that does not answer waits for it (a minute in configs/zenoh/); each
/// role stops at Ctrl-C instead, exit 130, and says so.
#[test]
fn roles_waiting_for_their_router_stop_at_ctrl_c() {
    let _fleet = fleet();
    let mission = paper("b-current");
    let client = format!("{}/configs/zenoh/shore.json5", env!("CARGO_MANIFEST_DIR"));
    // A listener that never accepts: connections wait in its backlog, Zenoh's handshake is never
    // answered, and the port stays ours for the test.
    let silent = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let endpoint = format!("tcp/{}", silent.local_addr().unwrap());
    let dir = scratch("waiting-sigint");
    let out = dir.join("run");
    let out = out.to_str().unwrap();
    let roles: [&[&str]; 4] = [
        &["planner", &mission],
        &["world", &mission],
        &["agent", &mission, "--id", "1"],
        &["record", &mission, "--out", out],
    ];
    let mut waiting: Vec<Reaper> = roles
        .iter()
        .map(|args| {
            Reaper(
                std::process::Command::new(env!("CARGO_BIN_EXE_tcpf"))
                    .args(*args)
                    .args(["-c", &client, "-e", &endpoint])
                    .args(["--credential", credential().to_str().unwrap()])
                    .stdout(std::process::Stdio::null())
                    .stderr(std::fs::File::create(dir.join(format!("{}.log", args[0]))).unwrap())
                    .spawn()
                    .unwrap(),
            )
        })
        .collect();
    for (role, child) in roles.iter().zip(&mut waiting) {
        // Into the session's opening, which it logs.
        let log = dir.join(format!("{}.log", role[0]));
        common::wait_for_text(&log, "connecting to", Duration::from_secs(30));
        assert!(
            child.0.try_wait().unwrap().is_none(),
            "{} waits for its router",
            role[0]
        );
        kill("-INT", child.0.id());
        let code = common::wait_exit(&mut child.0, Duration::from_secs(10), "a waiting role ignored Ctrl-C");
        let stderr = std::fs::read_to_string(&log).unwrap();
        assert_eq!(code, Some(130), "{}: {stderr}", role[0]);
        assert!(
            stderr.contains("interrupted while the Zenoh session was opening"),
            "{}: {stderr}",
            role[0]
        );
    }
}

/// A role pointed at a router that never answers says where it tries and gives up at its own
/// startup timeout, not at the config file's connect timeout (a minute in vehicle.json5).
#[test]
fn a_role_whose_router_never_answers_says_where_and_gives_up_at_its_startup_timeout() {
    let _fleet = fleet();
    // A port that takes connections and never speaks Zenoh.
    let silent = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let endpoint = format!("tcp/{}", silent.local_addr().unwrap());
    let vehicle = format!("{}/configs/zenoh/vehicle.json5", env!("CARGO_MANIFEST_DIR"));
    let o = tcpf(&[
        "agent",
        &paper("b-current"),
        "--id",
        "1",
        "-c",
        &vehicle,
        "--credential",
        credential().to_str().unwrap(),
        "-e",
        &endpoint,
        "--startup-timeout",
        "2",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        text(&o).contains(&format!("connecting to [\"{endpoint}\"]")),
        "{}",
        text(&o)
    );
    assert!(
        text(&o).contains(&format!(
            "nothing answered at [\"{endpoint}\"] within 2 s (--startup-timeout)"
        )),
        "{}",
        text(&o)
    );
}

/// Case (a) run in-process into a scratch directory `name`, for `tcpf report` to read again.
fn a_run_to_report(name: &str) -> std::path::PathBuf {
    let out = scratch(name);
    let o = tcpf(&[
        "run",
        &paper("a-nominal"),
        "--in-process",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    out
}

/// `tcpf report` of a run directory that lost a file: bad input, named.
#[test]
fn a_report_of_a_run_directory_without_its_telemetry_names_the_file() {
    let out = a_run_to_report("report-missing");
    std::fs::remove_file(out.join("telemetry.csv")).unwrap();
    let o = tcpf(&["report", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("telemetry.csv"), "{}", text(&o));
}

/// `tcpf report` of a lockstep run whose telemetry was cut short at a row's end: the report is
/// written from what is there, and says the file is short.
#[test]
fn a_report_of_a_cut_telemetry_says_so() {
    let out = a_run_to_report("report-cut");
    let telemetry = std::fs::read_to_string(out.join("telemetry.csv")).unwrap();
    let half: Vec<&str> = telemetry.lines().take(telemetry.lines().count() / 2).collect();
    std::fs::write(out.join("telemetry.csv"), half.join("\n") + "\n").unwrap();
    let o = tcpf(&["report", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("the file was cut short"), "{}", text(&o));
}

/// `tcpf report` of a crafted run directory: what summary.json says is escaped on the page
/// (a seed or an id that was markup reached report.html as markup), and a telemetry row of a
/// vehicle the mission does not have is refused (50 000 ids drew every pair of them: 6.5 GB).
#[test]
fn a_report_of_a_crafted_run_directory_writes_no_markup_and_no_stranger() {
    let out = a_run_to_report("report-crafted");
    let summary = out.join("summary.json");
    let whole_text = std::fs::read_to_string(&summary).unwrap();
    let whole: serde_json::Value = serde_json::from_str(&whole_text).unwrap();
    // Markup where the summary has text: written as text.
    let mut s = whole.clone();
    s["failure"] = "<script>alert(1)</script>".into();
    s["warnings"] = serde_json::json!(["<img src=x onerror=alert(2)>"]);
    std::fs::write(&summary, s.to_string()).unwrap();
    let o = tcpf(&["report", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        !html.contains("<script>") && !html.contains("<img"),
        "markup on the page"
    );
    assert!(html.contains("&lt;script&gt;alert(1)&lt;/script&gt;"));
    // Markup where the summary has a number: not a run's summary.
    let mut s = whole;
    s["seed"] = "<script>alert(1)</script>".into();
    s["vehicles"][0]["id"] = "<img src=x onerror=alert(2)>".into();
    std::fs::write(&summary, s.to_string()).unwrap();
    let o = tcpf(&["report", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("not the summary a run writes: invalid type: string"),
        "{}",
        text(&o)
    );
    std::fs::write(&summary, whole_text).unwrap();
    let telemetry = out.join("telemetry.csv");
    let mut rows = std::fs::read_to_string(&telemetry).unwrap();
    rows.push_str("5,0.05,50000,0,0,0,0,0.5,0,0.5,0,0,0\n");
    std::fs::write(&telemetry, rows).unwrap();
    let o = tcpf(&["report", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("vehicle 50000 is not one of the mission's (mission.toml)"),
        "{}",
        text(&o)
    );
}

/// A mission file far longer than any mission: refused before it is read whole (an 80 MB file,
/// valid but padded, took 3.8 GB to plan).
#[test]
fn a_mission_file_beyond_any_missions_size_is_refused() {
    let dir = scratch("huge-mission");
    let file = dir.join("huge.toml");
    let mut body = std::fs::read_to_string(paper("b-current")).unwrap();
    let padding = format!("# {}\n", "x".repeat(1000));
    while body.len() <= 5 << 20 {
        body.push_str(&padding);
    }
    std::fs::write(&file, body).unwrap();
    let o = tcpf(&["plan", file.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("a mission file is at most 4 MiB"), "{}", text(&o));
}

/// `tcpf report` of a run directory missing its messages, with a summary cut short, another JSON
/// document in its place, or none.
#[test]
fn a_report_of_a_damaged_run_directory_says_what_is_wrong() {
    let out = a_run_to_report("report-damaged");
    std::fs::remove_file(out.join("messages.csv")).unwrap();
    let o = tcpf(&["report", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("messages.csv: no such file: the report's message plots are empty"),
        "{}",
        text(&o)
    );
    let summary = out.join("summary.json");
    let whole = std::fs::read_to_string(&summary).unwrap();
    std::fs::write(&summary, &whole[..whole.len() / 2]).unwrap();
    let o = tcpf(&["report", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains(&format!("{}: not the JSON a run writes", summary.display())),
        "{}",
        text(&o)
    );
    std::fs::write(&summary, "{}").unwrap();
    let o = tcpf(&["report", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains(&format!(
            "{}: not the summary a run writes: missing field `mission`",
            summary.display()
        )),
        "{}",
        text(&o)
    );
    std::fs::remove_file(&summary).unwrap();
    let o = tcpf(&["report", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("a run stopped before it wrote one"), "{}", text(&o));
}

/// A router given no endpoint listens on a port of its choosing, and says which: a client can
/// connect where the log says.
#[test]
fn a_bare_router_names_the_port_it_got() {
    let _fleet = fleet();
    use std::io::{BufRead, BufReader};
    let mut router = Reaper(
        std::process::Command::new(env!("CARGO_BIN_EXE_tcpf"))
            .args(["router", "--open"])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let stderr = router.0.stderr.take().unwrap();
    let (lines, said) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = lines.send(line);
        }
    });
    let line = loop {
        let line = said
            .recv_timeout(Duration::from_secs(30))
            .expect("the router says where it listens within 30 s");
        if line.contains("listening on") {
            break line;
        }
    };
    let port: u16 = line
        .rsplit("tcp/127.0.0.1:")
        .next()
        .and_then(|p| p.trim().parse().ok())
        .unwrap_or_else(|| panic!("no loopback port in: {line}"));
    assert_ne!(port, 0, "{line}");
    std::net::TcpStream::connect(("127.0.0.1", port)).unwrap_or_else(|e| panic!("{line}: {e}"));
    kill("-TERM", router.0.id());
    let deadline = Instant::now() + Duration::from_secs(10);
    let status = loop {
        if let Some(status) = router.0.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "the router ignored SIGTERM");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(status.code(), Some(0));
}

/// `tcpf bench` stopped by a signal measured nothing: it says so, exits 130, and leaves no child
/// and no scratch directory, whether it was timing round trips or running the fleet.
#[test]
fn an_interrupted_bench_prints_no_figures_and_leaves_nothing() {
    let _fleet = fleet();
    use std::io::Read;
    let dir = scratch("bench-interrupted");
    let mission = common::lanes(&dir, 3);
    // Round trips counted in the millions never end; a few, and the fleet comes soon.
    for (signal, child, count) in [("-TERM", "pong", "100000000"), ("-INT", "agent", "200")] {
        let mut bench = Reaper(
            std::process::Command::new(env!("CARGO_BIN_EXE_tcpf"))
                .args(["bench", mission.to_str().unwrap(), "--count", count])
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap(),
        );
        let pid = bench.0.id();
        let role_of = |p: u32| {
            std::fs::read(format!("/proc/{p}/cmdline")).ok().and_then(|c| {
                c.split(|&b| b == 0)
                    .nth(1)
                    .map(|r| String::from_utf8_lossy(r).to_string())
            })
        };
        let deadline = Instant::now() + Duration::from_secs(120);
        let children = loop {
            let children = common::descendants(pid);
            if children.iter().any(|&p| role_of(p).as_deref() == Some(child)) {
                break children;
            }
            assert!(Instant::now() < deadline, "no {child} under the bench");
            std::thread::sleep(Duration::from_millis(20));
        };
        kill(signal, pid);
        let (code, stderr) = exited(&mut bench.0, Duration::from_secs(30), "the bench ignored the signal");
        assert_eq!(code, Some(130), "{signal}: {stderr}");
        assert!(stderr.contains("interrupted: no figures"), "{stderr}");
        let mut stdout = String::new();
        bench.0.stdout.take().unwrap().read_to_string(&mut stdout).unwrap();
        assert!(!stdout.contains("lockstep tick"), "{signal}: {stdout}");
        let left: Vec<u32> = children.into_iter().filter(|&p| common::alive(p)).collect();
        assert!(left.is_empty(), "{signal}: children left: {left:?}");
        assert!(!std::env::temp_dir().join(format!("tcpf-bench-{pid}")).exists());
    }
}

/// `tcpf report` of a sweep's directory says what it is, rather than "not a run directory".
#[test]
fn a_report_of_a_sweeps_directory_says_it_reads_one_run() {
    let out = scratch("report-sweep");
    let o = a_small_sweep(&out);
    assert!(o.status.success(), "{}", text(&o));
    let o = tcpf(&["report", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("a sweep's directory (runs.csv)"), "{}", text(&o));
}

/// A run directory says what made it, so that the run can be told apart and made again: the
/// command, tcpf's version and the commit it was built from (where built from a checkout, as
/// here), the digest of the mission as run (its `mission.toml`, overrides applied), in
/// summary.json and on report.html's first screen with the mission's main parameters.
#[test]
fn a_run_directory_says_what_made_it() {
    let out = scratch("provenance");
    let mission = paper("b-current");
    let args = [
        "run",
        &mission,
        "--in-process",
        "--seed",
        "3",
        "--set",
        "comms.loss=0.2",
        "--out",
        out.to_str().unwrap(),
    ];
    let o = tcpf(&args);
    assert!(o.status.success(), "{}", text(&o));
    let s = common::summary(&out);
    let as_run = std::fs::read_to_string(out.join("mission.toml")).unwrap();
    assert!(as_run.contains("loss = 0.2"), "the override is in the mission as run");
    let command = common::assert_provenance(&s["provenance"], &args, &as_run);
    let digest = format!("{:016x}", tcpf_core::mission::digest_of(&as_run));
    assert_eq!(s["seed"], 3);
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let first_screen = &html[..html.find("<figure").unwrap_or(html.len())];
    for shown in [&command[..], &digest, "loss 0.2", "k_c 0.5", env!("CARGO_PKG_VERSION")] {
        assert!(first_screen.contains(shown), "{shown} not on the first screen");
    }
}

/// A build of a modified tree says so in every run's provenance: its commit gains `-dirty` when
/// a tracked file changed or an untracked one (not ignored) was added, and not before.
#[test]
fn a_modified_tree_records_its_commit_as_dirty() {
    let dir = scratch("dirty");
    let git = |args: &[&str]| {
        let o = Command::new("git")
            .args([
                "-c",
                "user.name=t",
                "-c",
                "user.email=t@t",
                "-c",
                "init.defaultBranch=main",
            ])
            .args(args)
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(o.status.success(), "git {args:?}: {}", text(&o));
    };
    git(&["init", "-q"]);
    std::fs::write(dir.join(".gitignore"), "/runs\n").unwrap();
    std::fs::write(dir.join("a.rs"), "fn a() {}\n").unwrap();
    git(&["add", "."]);
    git(&["commit", "-q", "-m", "a"]);
    let clean = commit_of(&dir).unwrap();
    assert_eq!(clean.len(), 40, "{clean}");
    std::fs::create_dir_all(dir.join("runs")).unwrap();
    std::fs::write(dir.join("runs/x"), "ignored").unwrap();
    assert_eq!(commit_of(&dir).unwrap(), clean, "an ignored file changes nothing");
    std::fs::write(dir.join("a.rs"), "fn a() { }\n").unwrap();
    assert_eq!(commit_of(&dir).unwrap(), format!("{clean}-dirty"));
    git(&["checkout", "-q", "a.rs"]);
    std::fs::write(dir.join("b.rs"), "fn b() {}\n").unwrap();
    assert_eq!(commit_of(&dir).unwrap(), format!("{clean}-dirty"), "a new file");
    assert!(commit_of(&std::env::temp_dir().join("no-such-checkout")).is_none());
}

/// Every run directory runs itself again: `rerun.sh` from the directory's own mission.toml, in
/// the mode it ran in, records the same telemetry byte for byte.
#[test]
fn a_run_directory_runs_itself_again_with_rerun_sh() {
    let dir = scratch("rerun-run");
    let first = dir.join("first");
    let o = tcpf(&[
        "run",
        &paper("b-current"),
        "--in-process",
        "--seed",
        "7",
        "--set",
        "comms.loss=0.2",
        "--out",
        first.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let again = dir.join("again");
    let o = Command::new("sh")
        .arg(first.join("rerun.sh"))
        .arg(&again)
        .env("TCPF", env!("CARGO_BIN_EXE_tcpf"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    for file in ["telemetry.csv", "messages.csv"] {
        assert_eq!(
            std::fs::read(first.join(file)).unwrap(),
            std::fs::read(again.join(file)).unwrap(),
            "{file}"
        );
    }
}
