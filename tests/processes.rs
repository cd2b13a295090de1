//! `tcpf run` as a fleet of processes over Zenoh, spawned as a user would. Every test kills what
//! it started, whatever happens, and checks that no process is left behind.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{
    agent_under, alive, arrivals, assert_none_left, assert_same_run, child_of, config, credentialed, csv_rows,
    descendants, exited, failure, fleet, kill, lanes, listening, paper, pid_of, processes, record_by_hand,
    run_in_process, scratch, stop_the_planner, summary, usrpwd, wait_exit, wait_for_text, wait_until_simulated,
    went_on_without_its_planner, Launch, Reaper,
};

#[test]
fn processes_and_in_process_are_bit_identical() {
    let _fleet = fleet();
    for (case, seed) in [
        ("a-nominal", "1"),
        ("b-current", "1"),
        ("c-uncoordinated", "1"),
        ("d-lossy", "1"),
    ] {
        let dir = scratch(&format!("identical-{case}"));
        let mut launch = Launch::start(&paper(case), &dir.join("p"), &["--seed", seed]);
        assert!(launch.wait(Duration::from_secs(180)).success());
        run_in_process(&paper(case), &dir.join("i"), &["--seed", seed]);
        assert_same_run(&dir.join("p"), &dir.join("i"));
        let s = launch.summary();
        eprintln!(
            "{case}: {} ticks in {:.2} s of wall time, {:.1}× real time, {:.0} µs a tick",
            s["ticks"],
            s["wall_time_s"].as_f64().unwrap(),
            s["sim_time_s"].as_f64().unwrap() / s["wall_time_s"].as_f64().unwrap(),
            1e6 * s["wall_time_s"].as_f64().unwrap() / s["ticks"].as_f64().unwrap()
        );
        // How long the launch took to its first tick: said by a fleet of processes, not by a
        // run that launched none.
        let first = s["first_tick_s"].as_f64().unwrap();
        assert!(first > 0.0 && first < s["wall_time_s"].as_f64().unwrap(), "{s}");
        assert!(summary(&dir.join("i")).get("first_tick_s").is_none());
        assert_none_left(&s);
    }
}

#[test]
fn each_link_model_runs_the_same_as_processes() {
    let _fleet = fleet();
    let ring5 = config("ring5");
    for (name, mission, extra) in [
        ("delay", paper("b-current"), &["--set", "comms.delay=2"][..]),
        ("event", ring5.clone(), &["--set", "comms.trigger=\"event\""][..]),
        ("tdma", ring5, &["--set", "comms.tdma_slot=1"][..]),
        ("acoustic", config("acoustic"), &[][..]),
    ] {
        let dir = scratch(&format!("model-{name}"));
        let mut launch = Launch::start(&mission, &dir.join("p"), extra);
        assert!(launch.wait(Duration::from_secs(300)).success(), "{name}");
        run_in_process(&mission, &dir.join("i"), extra);
        assert_same_run(&dir.join("p"), &dir.join("i"));
        let s = launch.summary();
        let sent: Vec<u64> = s["vehicles"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v["gamma_sent"].as_u64().unwrap())
            .collect();
        eprintln!(
            "{name}: γ broadcasts per vehicle {sent:?}, error {}",
            s["max_coordination_error"]
        );
        assert_none_left(&s);
    }
}

/// The acoustic modem (docs/LINKS.md) as processes: every agent hears every vehicle's frames,
/// so lockstep waits for them all; the physics' decisions are the in-process run's, bit for bit.
#[test]
fn a_fleet_on_acoustic_modems_runs_the_same_as_processes() {
    let _fleet = fleet();
    let modem = config("acoustic-modem");
    for (name, mission, extra) in [
        ("periodic", paper("b-current"), &["--set", "comms.modem={}"][..]),
        ("tdma", modem.clone(), &[][..]),
        ("half-duplex", modem, &["--set", "comms.tdma_slot=0.1"][..]),
        (
            "line-events",
            config("ring5"),
            &[
                "--set",
                "comms.modem={}",
                "--set",
                "comms.topology=\"line\"",
                "--set",
                "comms.trigger=\"event\"",
            ][..],
        ),
    ] {
        let dir = scratch(&format!("modem-{name}"));
        let mut launch = Launch::start(&mission, &dir.join("p"), extra);
        assert!(launch.wait(Duration::from_secs(300)).success(), "{name}");
        run_in_process(&mission, &dir.join("i"), extra);
        assert_same_run(&dir.join("p"), &dir.join("i"));
        let rows = csv_rows(&dir.join("p/messages.csv"));
        let mut causes = std::collections::BTreeMap::<String, u64>::new();
        for r in &rows {
            *causes.entry(r["cause"].clone()).or_default() += 1;
            assert_eq!(r["delivered"] == "1", r["cause"] == "delivered", "{r:?}");
            let (sent, judged) = (r["sent_t"].parse::<f64>().unwrap(), r["t"].parse::<f64>().unwrap());
            match r["cause"].as_str() {
                "busy" => assert_eq!(sent, judged, "never sent: {r:?}"),
                _ => assert!(sent < judged, "judged when its last bit is in: {r:?}"),
            }
        }
        let s = launch.summary();
        eprintln!(
            "{name}: frames by cause {causes:?}, error {}",
            s["max_coordination_error"]
        );
        let summed: u64 = s["links"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|l| l["causes"].as_object().unwrap().values())
            .map(|n| n.as_u64().unwrap())
            .sum();
        assert_eq!(summed as usize, rows.len(), "the summary counts every row by cause");
        match name {
            "periodic" => {
                // The paper's exchange on default modems: every frame lost to half duplex, and
                // the fleet arrives as if every message were lost.
                assert_eq!(causes.keys().collect::<Vec<_>>(), ["busy", "half_duplex"]);
                run_in_process(&mission, &dir.join("lost"), &["--set", "comms.loss=1"]);
                assert_eq!(arrivals(&s), arrivals(&summary(&dir.join("lost"))));
            }
            "tdma" => assert_eq!(causes.keys().collect::<Vec<_>>(), ["delivered"]),
            "half-duplex" => assert_eq!(causes.keys().collect::<Vec<_>>(), ["half_duplex"]),
            _ => assert!(causes.get("collision").is_some_and(|&n| n > 0), "{causes:?}"),
        }
        // The report draws each frame by its cause, and the error rate against distance.
        let report = std::fs::read_to_string(dir.join("p/report.html")).unwrap();
        for cause in causes.keys() {
            let legend = format!("\n{}\n</text>", cause.replace('_', " "));
            assert!(report.contains(&legend), "legend {cause}");
        }
        let drawn = report.contains("id=\"frame-errors\"");
        let undecided = ["half-duplex", "periodic"].contains(&name);
        assert_eq!(drawn, !undecided, "frames the error draw decided: none in half duplex");
        assert_none_left(&s);
    }
}

#[test]
fn a_medusa_fleet_and_a_mixed_fleet_run_the_same_as_processes() {
    let _fleet = fleet();
    for (name, mission, extra) in [
        ("medusa", config("medusa/b-current"), &[][..]),
        (
            "mixed",
            paper("b-current"),
            &["--set", "vehicle.2.vehicle_model={ kind = \"medusa\" }"][..],
        ),
    ] {
        let dir = scratch(&format!("dynamics-{name}"));
        let mut launch = Launch::start(&mission, &dir.join("p"), extra);
        assert!(launch.wait(Duration::from_secs(180)).success(), "{name}");
        run_in_process(&mission, &dir.join("i"), extra);
        assert_same_run(&dir.join("p"), &dir.join("i"));
        let telemetry = std::fs::read_to_string(dir.join("p/telemetry.csv")).unwrap();
        let header = telemetry.lines().next().unwrap();
        assert!(
            header.ends_with(",surge,sway,yaw_rate,beta,command_1,command_2,motor_1,motor_2,thrust_1,thrust_2"),
            "{header}"
        );
        let s = launch.summary();
        let arrivals = arrivals(&s);
        eprintln!("{name}: arrivals {arrivals:?}, error {}", s["max_coordination_error"]);
        assert_none_left(&s);
    }
}

#[test]
fn every_role_runs_in_its_own_process() {
    let _fleet = fleet();
    let dir = scratch("pids");
    let mut launch = Launch::start(&paper("b-current"), &dir, &[]);
    assert!(launch.wait(Duration::from_secs(180)).success());
    let s = launch.summary();
    let children = s["children"].as_array().unwrap();
    let roles: Vec<(&str, u64)> = children
        .iter()
        .map(|c| (c["role"].as_str().unwrap(), c["id"].as_u64().unwrap()))
        .collect();
    assert_eq!(roles, vec![("planner", 0), ("world", 0), ("agent", 1), ("agent", 2)]);
    let mut pids: Vec<u64> = children.iter().map(|c| c["pid"].as_u64().unwrap()).collect();
    for c in children {
        assert_eq!(
            c["pid"], c["reported_pid"],
            "the role reported from the process the launcher started"
        );
        assert_eq!(c["exit_code"], 0);
        assert_ne!(c["pid"].as_u64().unwrap(), launch.child.id() as u64);
    }
    pids.sort_unstable();
    pids.dedup();
    assert_eq!(pids.len(), 4, "distinct pids");
    assert_none_left(&s);
    for f in ["planner.log", "world.log", "agent-1.log", "agent-2.log"] {
        assert!(dir.join("logs").join(f).is_file(), "{f}");
    }
}

#[test]
fn a_ring_of_five_completes() {
    let _fleet = fleet();
    let mission = config("ring5");
    let dir = scratch("ring5");
    let mut launch = Launch::start(&mission, &dir.join("p"), &[]);
    assert!(launch.wait(Duration::from_secs(300)).success());
    let s = launch.summary();
    assert_eq!(s["completed"], true);
    assert_eq!(s["vehicles"].as_array().unwrap().len(), 5);
    assert_eq!(
        s["links"].as_array().unwrap().len(),
        10,
        "a ring of five has ten directed links"
    );
    run_in_process(&mission, &dir.join("i"), &[]);
    assert_same_run(&dir.join("p"), &dir.join("i"));
    assert_none_left(&s);
}

#[test]
fn a_fleet_of_ten_is_routed_by_its_world_and_every_process_reports() {
    let _fleet = fleet();
    let dir = scratch("routed-by-the-world");
    let mission = lanes(&dir, 10);
    let out = dir.join("p");
    let mut launch = Launch::start(mission.to_str().unwrap(), &out, &[]);
    assert!(launch.wait(Duration::from_secs(300)).success());
    // The world listens; every other process, the launcher too, connects to it.
    let json = |f: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(out.join(f)).unwrap()).unwrap()
    };
    let endpoint = std::fs::read_to_string(out.join("endpoint")).unwrap();
    assert_eq!(json("world.json5")["mode"], "router");
    assert_eq!(json("world.json5")["listen"]["endpoints"][0], endpoint.trim());
    assert_eq!(json("zenoh.json5")["mode"], "client");
    assert_eq!(json("zenoh.json5")["connect"]["endpoints"][0], endpoint.trim());
    // A world that forwarded on one thread with congestion control block waited, now and then,
    // on a queue only that thread could drain: the run stalled at its end, the world and the
    // planner were killed and no report reached the recorder (4 runs in 10).
    let s = launch.summary();
    let children = s["children"].as_array().unwrap();
    assert_eq!(children.len(), 12);
    for c in children {
        assert_eq!(c["exit_code"], 0, "{c}");
        assert_eq!(c["pid"], c["reported_pid"], "{c}");
    }
    assert_none_left(&s);
}

#[test]
fn an_interrupted_fleet_of_ten_hears_from_every_process() {
    let _fleet = fleet();
    let dir = scratch("interrupted-ten");
    let mission = lanes(&dir, 10);
    // An agent that closed its session as soon as it had reported lost the report now and then
    // (1 run in 6): three runs, stopped by Ctrl-C, SIGTERM and the terminal closing (SIGHUP).
    for (run, signal) in ["-INT", "-TERM", "-HUP"].into_iter().enumerate() {
        let out = dir.join(format!("p{run}"));
        // About 6 s of ticks, to be stopped a few hundred ticks in on any machine.
        let slower = ["--set", "mission.control_period=0.005"];
        let mut launch = Launch::start(mission.to_str().unwrap(), &out, &slower);
        wait_until_simulated(&out, 1.5);
        kill(signal, launch.child.id());
        assert_eq!(launch.wait(Duration::from_secs(10)).code(), Some(130), "{signal}");
        let s = launch.summary();
        assert_eq!(s["interrupted"], true, "{signal}");
        for c in s["children"].as_array().unwrap() {
            assert!(c["exit_code"].is_i64(), "run {run}: {c}");
            assert_eq!(c["pid"], c["reported_pid"], "run {run}: {c}");
        }
    }
}

#[test]
fn a_world_that_cannot_listen_fails_the_run_at_once_in_its_own_words() {
    let _fleet = fleet();
    // The launcher finds a free port, which the world binds: another process can take it in
    // between. Widen that moment (strace delays the world's exec by 2 s) and take the port.
    let dir = scratch("port-taken");
    let mut launch = run_with_a_slow_world(&dir);
    let world: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("world.json5")).unwrap()).unwrap();
    let endpoint = world["listen"]["endpoints"][0].as_str().unwrap();
    let port: u16 = endpoint.rsplit(':').next().unwrap().parse().unwrap();
    let _taken = std::net::TcpListener::bind(("127.0.0.1", port)).unwrap();
    // Well before the minute a client of the run waits for its router.
    let status = launch.wait(Duration::from_secs(30));
    assert_eq!(status.code(), Some(1));
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut launch.child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert!(stderr.contains("the world exited (code 1) as it started"), "{stderr}");
    assert!(stderr.contains("Address already in use"), "{stderr}");
    assert!(!stderr.contains(".rs:"), "no source paths: {stderr}");
    assert!(dir.join("logs/world.log").is_file());
    assert!(!dir.join("endpoint").exists(), "nobody was told to join");
    // The planner, started beside the world, went with it.
    assert!(dir.join("logs/planner.log").is_file());
    // A run directory all the same: its summary says why, with no tick.
    let s = launch.summary();
    assert!(failure(&s).contains("the world exited (code 1) as it started"), "{s}");
    assert_eq!(
        (&s["completed"], &s["ticks"]),
        (&serde_json::json!(false), &serde_json::json!(0))
    );
    assert_eq!(child_of(&s, "world")["exit_code"], 1, "{s}");
    let telemetry = std::fs::read_to_string(dir.join("telemetry.csv")).unwrap();
    assert_eq!(telemetry.lines().count(), 1, "the header alone");
    assert!(std::fs::read_to_string(dir.join("report.html"))
        .unwrap()
        .contains("Failed:"));
    let run = dir.display().to_string();
    let left: Vec<u32> = processes()
        .into_iter()
        .filter(|&(pid, _, state)| {
            state != 'Z'
                && std::fs::read(format!("/proc/{pid}/cmdline"))
                    .is_ok_and(|c| String::from_utf8_lossy(&c).contains(&run))
        })
        .map(|p| p.0)
        .collect();
    assert!(left.is_empty(), "processes of the run outlived it: {left:?}");
}

/// tcpf under strace, its first child's exec (the world's) delayed by 2 s: the moment while the
/// world starts, widened.
fn strace_with_a_slow_world() -> Command {
    strace_with_a_slow_world_of(Path::new(env!("CARGO_BIN_EXE_tcpf")))
}

/// `tcpf` at `exe` under strace, which holds each process's first execve for 2 s: a world
/// whose start is slow.
fn strace_with_a_slow_world_of(exe: &Path) -> Command {
    let mut strace = Command::new("strace");
    strace.args([
        "-f",
        "-qq",
        "-o",
        "/dev/null",
        "-e",
        "trace=execve",
        "-e",
        "inject=execve:delay_exit=2000000:when=1",
    ]);
    strace.arg(exe);
    strace
}

/// `tcpf run` with a slow world, once the world is starting.
fn run_with_a_slow_world(dir: &Path) -> Launch {
    let launch = Launch::spawn(strace_with_a_slow_world(), &paper("b-current"), dir, &[]);
    launch.wait_for("world.json5", "router");
    launch
}

/// The tcpf that strace (`strace`) runs: its child.
fn traced(strace: u32) -> u32 {
    processes()
        .into_iter()
        .find(|p| p.1 == strace)
        .map(|p| p.0)
        .expect("tcpf runs under strace")
}

/// Agents that cannot be started fail the run before its first tick: the world and the planner
/// go, and the run directory says why, as for a world that could not start.
#[test]
fn agents_that_cannot_be_started_fail_the_run_with_its_run_directory_written() {
    let _fleet = fleet();
    let dir = scratch("agents-unstarted");
    // A copy of tcpf, removed while the world it started is held at its start: the launcher
    // cannot start the agents from it.
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let exe = bin.join("tcpf");
    std::fs::copy(env!("CARGO_BIN_EXE_tcpf"), &exe).unwrap();
    let out = dir.join("run");
    let mut launch = Launch::spawn(strace_with_a_slow_world_of(&exe), &paper("b-current"), &out, &[]);
    let role = |pid: u32| {
        let cmdline = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
        cmdline.split(|b| *b == 0).nth(1).map(<[u8]>::to_vec)
    };
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let roles: Vec<_> = descendants(launch.child.id()).into_iter().filter_map(role).collect();
        if [&b"world"[..], b"planner"]
            .iter()
            .all(|r| roles.iter().any(|have| have == r))
        {
            break;
        }
        assert!(Instant::now() < deadline, "no world and planner under the launcher");
        std::thread::sleep(Duration::from_millis(20));
    }
    std::fs::remove_file(&exe).unwrap();
    let status = launch.wait(Duration::from_secs(30));
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut launch.child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert_eq!(status.code(), Some(1), "{stderr}");
    let why = format!("cannot start {} agent 1", exe.display());
    assert!(stderr.contains(&why), "{stderr}");
    let s = launch.summary();
    assert!(failure(&s).starts_with(&why), "{s}");
    assert_eq!(
        (&s["completed"], &s["interrupted"], &s["ticks"]),
        (
            &serde_json::json!(false),
            &serde_json::json!(false),
            &serde_json::json!(0)
        )
    );
    // From the launch, while strace held the world 2 s; and no tick to time.
    assert!(s["wall_time_s"].as_f64().unwrap() > 1.0, "{s}");
    assert_eq!(s["tick_wall_time_us"], 0.0, "{s}");
    assert!(s.get("first_tick_s").is_none(), "{s}");
    assert!(s["children"]
        .as_array()
        .unwrap()
        .iter()
        .all(|c| c["exit_code"].is_i64() || c["signal"].is_i64()));
    let html =
        std::fs::read_to_string(out.join("report.html")).unwrap_or_else(|e| panic!("report.html: {e}: {stderr}"));
    assert!(html.contains("Failed:"));
    assert!(
        descendants(launch.child.id()).is_empty(),
        "the world and the planner went"
    );
}

#[test]
fn ctrl_c_while_the_world_starts_leaves_a_run_directory_that_says_so() {
    let _fleet = fleet();
    let dir = scratch("interrupted-start");
    let mut launch = run_with_a_slow_world(&dir);
    kill("-INT", traced(launch.child.id()));
    let status = launch.wait(Duration::from_secs(30));
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut launch.child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert_eq!(status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted while the world was starting"), "{stderr}");
    let s = launch.summary();
    assert_eq!(
        (&s["interrupted"], &s["completed"]),
        (&serde_json::json!(true), &serde_json::json!(false))
    );
    assert_eq!(
        (&s["ticks"], &s["failure"]),
        (&serde_json::json!(0), &serde_json::Value::Null)
    );
    assert!(dir.join("report.html").is_file() && dir.join("telemetry.csv").is_file());
}

/// `tcpf sweep` (run by `command`) of case (b) at two losses, a seed each, as fleets of
/// processes, into `out`.
fn sweep_of_fleets(mut command: Command, out: &Path, extra: &[&str]) -> Reaper {
    Reaper(
        command
            .args([
                "sweep",
                &paper("b-current"),
                "--loss",
                "0,0.5",
                "--seeds",
                "1",
                "--processes",
            ])
            .args(["--out", out.to_str().unwrap()])
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
    )
}

#[test]
fn a_sweep_of_fleets_stopped_as_a_world_starts_is_an_interrupted_sweep() {
    let _fleet = fleet();
    let dir = scratch("sweep-interrupted-start");
    let out = dir.join("sweep");
    let mut sweep = sweep_of_fleets(strace_with_a_slow_world(), &out, &[]);
    wait_for_text(&out.join("runs/0-seed1/world.json5"), "router", Duration::from_secs(30));
    kill("-INT", traced(sweep.0.id()));
    let (code, stderr) = exited(&mut sweep.0, Duration::from_secs(30), "the sweep ignored Ctrl-C");
    assert_eq!(code, Some(130), "{stderr}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sweep.json")).unwrap()).unwrap();
    assert_eq!(
        (&summary["interrupted"], &summary["done_runs"]),
        (&serde_json::json!(true), &serde_json::json!(0))
    );
}

/// A fleet of a sweep that fails (its world killed) is named in the sweep's summary and left out
/// of its statistics; the sweep goes on with the next run, and exits 1 at the end.
#[test]
fn a_sweep_of_fleets_goes_on_past_a_failed_run_and_names_it() {
    let _fleet = fleet();
    let dir = scratch("sweep-failed-run");
    let out = dir.join("sweep");
    // About 4 s of ticks: the first run's world is killed well before its end.
    let slower = ["--set", "mission.control_period=0.002"];
    let mut sweep = sweep_of_fleets(Command::new(env!("CARGO_BIN_EXE_tcpf")), &out, &slower);
    wait_for_text(
        &out.join("runs/0-seed1/logs/world.log"),
        "starting",
        Duration::from_secs(60),
    );
    kill("-9", world_pid(sweep.0.id()));
    let (code, stderr) = exited(&mut sweep.0, Duration::from_secs(120), "the sweep never ended");
    let mut stdout = String::new();
    std::io::Read::read_to_string(sweep.0.stdout.as_mut().unwrap(), &mut stdout).unwrap();
    assert_eq!(code, Some(1), "{stderr}");
    let why = "the world exited (killed by signal 9) before the end";
    assert!(stderr.contains(why), "{stderr}");
    assert!(
        stdout.contains(&format!("FAILED: comms.loss = 0, seed 1: {why}")),
        "{stdout}"
    );
    assert!(
        stdout.contains("1 of 2 runs failed: the statistics are over the 1 done"),
        "{stdout}"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sweep.json")).unwrap()).unwrap();
    assert_eq!(
        (&summary["interrupted"], &summary["done_runs"]),
        (&serde_json::json!(false), &serde_json::json!(1))
    );
    let failed = &summary["failed_runs"][0];
    assert_eq!(
        (&failed["point"], &failed["seed"]),
        (&serde_json::json!("comms.loss = 0"), &serde_json::json!(1))
    );
    assert!(failed["failure"].as_str().unwrap().starts_with(why), "{failed}");
    let run = std::path::PathBuf::from(failed["run_dir"].as_str().unwrap());
    assert_eq!(run, out.join("runs/0-seed1"));
    let failed_run: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap()).unwrap();
    assert!(failure(&failed_run).starts_with(why), "{failed_run}");
    // The statistics are those of the run that was done; the failed one is counted, no more.
    let points = summary["points"].as_array().unwrap();
    let counts: Vec<_> = points
        .iter()
        .map(|p| (p["values"][0].as_str(), p["runs"].as_u64(), p["failed"].as_u64()))
        .collect();
    assert_eq!(
        counts,
        [(Some("0"), Some(1), Some(1)), (Some("0.5"), Some(1), Some(0))],
        "{summary}"
    );
    assert_eq!(points[0]["metrics"]["max_coordination_error"], serde_json::Value::Null);
    let csv = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 2, "the failed run and the run done: {csv}");
    // An empty cell for each of the 18 metrics (9 of the fleet, 9 frames by cause).
    assert_eq!(rows[0], format!("0,0,1,failed{}", ",".repeat(18)), "{csv}");
    assert!(rows[1].starts_with("1,0.5,1,arrived,"), "{csv}");
}

/// A fleet of a sweep whose world cannot listen fails as it starts: named, and the sweep goes on.
#[test]
fn a_sweep_of_fleets_goes_on_past_a_world_that_could_not_start() {
    let _fleet = fleet();
    let dir = scratch("sweep-world-unstarted");
    let out = dir.join("sweep");
    let mut sweep = sweep_of_fleets(strace_with_a_slow_world(), &out, &[]);
    let config = out.join("runs/0-seed1/world.json5");
    wait_for_text(&config, "router", Duration::from_secs(30));
    let world: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(config).unwrap()).unwrap();
    let endpoint = world["listen"]["endpoints"][0].as_str().unwrap();
    let port: u16 = endpoint.rsplit(':').next().unwrap().parse().unwrap();
    let taken = std::net::TcpListener::bind(("127.0.0.1", port)).unwrap();
    let (code, stderr) = exited(&mut sweep.0, Duration::from_secs(120), "the sweep never ended");
    drop(taken);
    assert_eq!(code, Some(1), "{stderr}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sweep.json")).unwrap()).unwrap();
    let failed = &summary["failed_runs"][0];
    assert_eq!(failed["point"], "comms.loss = 0", "{summary}");
    let why = failed["failure"].as_str().unwrap();
    assert!(why.contains("the world exited (code 1) as it started"), "{why}");
    assert_eq!(
        (&summary["done_runs"], &summary["points"][1]["values"][0]),
        (&serde_json::json!(1), &serde_json::json!("0.5"))
    );
    assert_eq!(summary["gave_up"], false);
}

#[test]
fn a_killed_agent_is_lost_and_the_others_arrive() {
    let _fleet = fleet();
    let dir = scratch("kill");
    let mut launch = Launch::start(&paper("b-current"), &dir, &[]);
    launch.wait_for("logs/world.log", "starting");
    kill("-9", agent_pid(&launch, 2));
    let status = launch.wait(Duration::from_secs(120));
    assert_eq!(status.code(), Some(1), "a lost vehicle fails the run");
    let s = launch.summary();
    assert_eq!(s["completed"], false);
    assert_eq!(s["vehicles"][1]["lost"], true);
    assert!(s["vehicles"][1]["arrival_time"].is_null());
    assert_eq!(s["vehicles"][0]["lost"], false);
    assert!(
        s["vehicles"][0]["arrival_time"].as_f64().is_some(),
        "vehicle 1 still arrives"
    );
    assert_none_left(&s);
    assert!(descendants(launch.child.id()).is_empty());
}

/// A mission whose vehicles do not arrive by its max_duration failed: the world, which alone
/// knows it in a fleet started by hand without a recorder, says so and exits 1.
#[test]
fn a_world_whose_vehicles_do_not_arrive_exits_1() {
    let _fleet = fleet();
    let dir = scratch("short");
    let mut launch = Launch::start(&paper("b-current"), &dir, &["--set", "mission.max_duration=20"]);
    assert_eq!(launch.wait(Duration::from_secs(120)).code(), Some(1));
    let s = launch.summary();
    let world = child_of(&s, "world");
    assert_eq!(world["exit_code"], 1, "{s}");
    let log = std::fs::read_to_string(dir.join("logs/world.log")).unwrap();
    assert!(
        log.contains("0 vehicle(s) lost, 2 not arrived by the mission's max_duration"),
        "{log}"
    );
}

/// Ctrl-Z on `tcpf run` (SIGTSTP), then `fg` (SIGCONT): the whole fleet stops with the launcher
/// and goes on with it, and a stop longer than the world's command timeout (10 s) and the
/// agents' stale timeout (3 s) costs no vehicle and no reproducibility. Once, the world cut the
/// stopped launcher's recorder off and ended the run unrecorded, and the run blamed the
/// planner.
#[test]
fn a_run_stopped_with_ctrl_z_goes_on_as_if_never_stopped() {
    let _fleet = fleet();
    let mission = config("long3");
    let dir = scratch("ctrl-z");
    let mut launch = Launch::start(&mission, &dir.join("p"), &[]);
    wait_until_simulated(&dir.join("p"), 1.0);
    kill("-TSTP", launch.child.id());
    std::thread::sleep(Duration::from_secs(12));
    kill("-CONT", launch.child.id());
    let status = launch.wait(Duration::from_secs(120));
    let s = launch.summary();
    assert!(status.success(), "{s}");
    assert_eq!(
        (&s["completed"], &s["reproducible"]),
        (&true.into(), &true.into()),
        "{s}"
    );
    assert!(s["wall_time_s"].as_f64().unwrap() > 12.0, "{}", s["wall_time_s"]);
    let world = std::fs::read_to_string(dir.join("p/logs/world.log")).unwrap();
    assert!(
        world.contains("world: resumed after"),
        "the world was stopped too: {world}"
    );
    run_in_process(&mission, &dir.join("i"), &[]);
    assert_same_run(&dir.join("p"), &dir.join("i"));
    assert_none_left(&s);
}

/// The launcher stopped alone (SIGSTOP, which it cannot handle, unlike Ctrl-Z's SIGTSTP): its
/// recorder reads nothing, the world cuts it off, and the recording has a hole. The run says
/// that the recorder lost it, not that the planner or the world failed.
#[test]
fn a_launcher_stopped_alone_names_its_recorders_loss() {
    let _fleet = fleet();
    let dir = scratch("sigstop-launcher");
    let mut launch = Launch::start(&config("long3"), &dir, &[]);
    wait_until_simulated(&dir, 1.0);
    kill("-STOP", launch.child.id());
    std::thread::sleep(Duration::from_secs(6));
    kill("-CONT", launch.child.id());
    let status = launch.wait(Duration::from_secs(120));
    let s = launch.summary();
    // Stopped at a good moment, the recorder may catch up: then the run is whole.
    if s["completed"] == true {
        assert!(status.success(), "{s}");
    } else {
        assert_eq!(status.code(), Some(1), "{s}");
        let why = failure(&s);
        assert!(
            why.starts_with("the recorder lost messages of tick") || why.starts_with("the recorder missed the end"),
            "{why}"
        );
    }
    assert_none_left(&s);
}

#[test]
fn an_agent_stopped_past_the_stale_timeout_never_passes_for_a_reproducible_run() {
    let _fleet = fleet();
    let dir = scratch("sigstop");
    let comms = ["--set", "comms.period=0.01"];
    let mut launch = Launch::start(&paper("b-current"), &dir.join("p"), &comms);
    launch.wait_for("logs/world.log", "starting");
    let agent = agent_pid(&launch, 2);
    // Where a stop lands is a race. Stopped before its γ of a tick, agent 2 is waited for by agent
    // 1, which gives up after the stale timeout; stopped between its γ and its command, it is
    // waited for by the world alone, for less than the world's command timeout, and the run is
    // rightly reproducible. Under load the second happens, about half the time: beside a CPU hog
    // five stops in a row once landed there. Stop again until agent 1 gave up, a few dozen ticks
    // apart, while the run lasts.
    let mut stops = 0;
    while stops < 12 && launch.child.try_wait().unwrap().is_none() {
        kill("-STOP", agent);
        std::thread::sleep(Duration::from_secs(5));
        kill("-CONT", agent);
        stops += 1;
        let agent1 = std::fs::read_to_string(dir.join("p/logs/agent-1.log")).unwrap_or_default();
        if agent1.contains("silent for") {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let status = launch.wait(Duration::from_secs(120));
    run_in_process(&paper("b-current"), &dir.join("i"), &comms);
    let s = launch.summary();
    let same =
        std::fs::read(dir.join("p/telemetry.csv")).unwrap() == std::fs::read(dir.join("i/telemetry.csv")).unwrap();
    eprintln!(
        "stopped {stops} times 5 s: exit {:?}, reproducible {}, identical telemetry {same}, reasons {}",
        status.code(),
        s["reproducible"],
        s["reproducible_reasons"]
    );
    if s["reproducible"] == true {
        assert!(same, "a run that calls itself reproducible is the in-process run");
        assert!(status.success());
    } else {
        assert_ne!(status.code(), Some(0), "an irreproducible run does not exit 0");
        let reasons = s["reproducible_reasons"].to_string();
        assert!(reasons.contains("agent 1"), "the agent that gave up says so: {reasons}");
        let unused = s["links"]
            .as_array()
            .unwrap()
            .iter()
            .find(|l| l["from"] == 2 && l["to"] == 1)
            .map(|l| l["unused"].as_u64().unwrap());
        assert!(
            unused > Some(0),
            "the link table counts the γ that came too late: {unused:?}"
        );
    }
    assert_eq!(s["reproducible"], false, "a 5 s stop outlasts the 3 s stale timeout");
    assert_none_left(&s);
}

#[test]
fn an_agent_stopped_past_the_worlds_bound_is_lost_as_silent_and_nothing_hangs() {
    let _fleet = fleet();
    let dir = scratch("sigstop-long");
    let bound = ["--command-timeout", "4"];
    let mut launch = Launch::start(&paper("b-current"), &dir, &bound);
    launch.wait_for("logs/world.log", "starting");
    let agent = agent_pid(&launch, 2);
    kill("-STOP", agent);
    std::thread::sleep(Duration::from_secs(7));
    kill("-CONT", agent);
    let status = launch.wait(Duration::from_secs(120));
    assert_eq!(status.code(), Some(1), "a run that lost a vehicle failed");
    let s = launch.summary();
    let v2 = &s["vehicles"][1];
    assert_eq!(v2["id"], 2);
    assert_eq!(v2["lost"], true, "{s}");
    assert_eq!(v2["lost_reason"], "silent", "{s}");
    assert!(s["vehicles"][0]["arrival_time"].is_number(), "vehicle 1 arrives: {s}");
    // When the world gave up is wall-clock time: not the in-process run.
    assert_eq!(s["reproducible"], false, "{s}");
    assert!(
        s["reproducible_reasons"]
            .to_string()
            .contains("vehicle 2 was lost (no command within"),
        "{s}"
    );
    let world = std::fs::read_to_string(dir.join("logs/world.log")).unwrap();
    assert!(world.contains("agent 2 sent no command"), "{world}");
    let agent2 = std::fs::read_to_string(dir.join("logs/agent-2.log")).unwrap();
    assert!(agent2.contains("the world gave up on this vehicle"), "{agent2}");
    assert_none_left(&s);
    assert!(descendants(launch.child.id()).is_empty());
}

#[test]
fn a_long_run_that_loses_an_agent_records_every_tick_and_counts_only_live_vehicles_after() {
    let _fleet = fleet();
    let dir = scratch("long-loss");
    let mut launch = Launch::start(&config("long3"), &dir, &[]);
    launch.wait_for("logs/world.log", "starting");
    let agent = agent_pid(&launch, 2);
    // 10 s of simulated time: 1000 ticks of three rows each.
    let deadline = Instant::now() + Duration::from_secs(60);
    while std::fs::read_to_string(dir.join("telemetry.csv")).map_or(0, |t| t.lines().count()) < 3000 {
        assert!(Instant::now() < deadline, "the run never reached 10 s");
        std::thread::sleep(Duration::from_millis(5));
    }
    kill("-9", agent);
    launch.wait_for("logs/world.log", "is gone at t = ");
    let log = std::fs::read_to_string(dir.join("logs/world.log")).unwrap();
    let at = log.split("is gone at t = ").nth(1).unwrap();
    let lost_tick = (at[..at.find(' ').unwrap()].parse::<f64>().unwrap() / 0.01).round() as usize;
    // The recorder learns of the loss as it happens and goes on writing, 30 s past it, before the
    // run ends (before, it held every tick after a loss until the end).
    while std::fs::read_to_string(dir.join("telemetry.csv")).map_or(0, |t| t.lines().count()) < 3 * (lost_tick + 3000) {
        let world = std::fs::read_to_string(dir.join("logs/world.log")).unwrap();
        assert!(
            !world.contains("world: ended"),
            "the world ended before the recorder wrote past the loss"
        );
        assert!(Instant::now() < deadline, "the recording stalls after the loss");
        std::thread::sleep(Duration::from_millis(5));
    }
    let status = launch.wait(Duration::from_secs(180));
    assert_eq!(status.code(), Some(1), "a lost vehicle fails the run");
    let s = launch.summary();
    let ticks = s["ticks"].as_u64().unwrap();
    assert!(
        ticks > 25_000,
        "it ran to the others' arrival, not to the loss: {ticks} ticks"
    );
    let telemetry = std::fs::read_to_string(dir.join("telemetry.csv")).unwrap();
    assert_eq!(telemetry.lines().count() as u64, 1 + 3 * ticks, "every tick recorded");
    assert_eq!(s["vehicles"][1]["lost"], true);
    assert!(
        s["reproducible_reasons"]
            .to_string()
            .contains("vehicle 2 was lost (its agent's process went away)"),
        "{s}"
    );
    for v in [0, 2] {
        assert!(
            s["vehicles"][v]["arrival_time"].as_f64().is_some(),
            "vehicle {} arrives",
            v + 1
        );
    }
    // The coordination error is over the vehicles that still have a command at each tick.
    let mut live_error = 0.0f64;
    let mut tick_rows: Vec<Vec<&str>> = Vec::new();
    for line in telemetry.lines().skip(1) {
        tick_rows.push(line.split(',').collect());
        if tick_rows.len() == 3 {
            let gammas: Vec<f64> = tick_rows.iter().filter_map(|r| r[6].parse().ok()).collect();
            for a in &gammas {
                for b in &gammas {
                    live_error = live_error.max((a - b).abs());
                }
            }
            tick_rows.clear();
        }
    }
    let reported = s["max_coordination_error_to_last_arrival"].as_f64().unwrap();
    eprintln!("lost at ~10 s of {ticks} ticks: coordination error {reported:.3} s over live vehicles");
    assert_eq!(reported, live_error, "only live vehicles count after the loss");
    assert!(reported < 2.0, "not the frozen γ of the lost vehicle: {reported}");
    assert_none_left(&s);
}

/// The pid of `tcpf agent --id <id>` under a launch.
fn agent_pid(launch: &Launch, id: u32) -> u32 {
    agent_under(launch.child.id(), id).unwrap_or_else(|| panic!("agent {id} runs"))
}

/// The pid of the world under `root` (a launch, a sweep).
fn world_pid(root: u32) -> u32 {
    pid_of(root, "the world", |args| args.get(1) == Some(&&b"world"[..]))
}

#[test]
fn a_run_whose_world_is_killed_says_so_in_its_summary_and_report() {
    let _fleet = fleet();
    let dir = scratch("world-killed");
    // Killed mid-run: past its first ticks (a run killed before any has nothing it could have done
    // otherwise, and stays reproducible), well before its end (about 1.7 s of ticks).
    let mut launch = Launch::start(&paper("b-current"), &dir, &["--set", "mission.control_period=0.005"]);
    wait_until_simulated(&dir, 1.0);
    kill("-9", world_pid(launch.child.id()));
    let status = launch.wait(Duration::from_secs(60));
    assert_eq!(status.code(), Some(1));
    let mut stderr = String::new();
    std::io::Read::read_to_string(launch.child.stderr.as_mut().unwrap(), &mut stderr).unwrap();
    let why = "the world exited (killed by signal 9) before the end";
    assert!(stderr.contains(why), "{stderr}");
    // What the console said is what the run directory keeps: not "vehicles not arrived" alone.
    let s = launch.summary();
    assert_eq!(s["completed"], false);
    assert!(failure(&s).starts_with(why), "{s}");
    let world = child_of(&s, "world");
    assert_eq!(
        (&world["exit_code"], &world["signal"]),
        (&serde_json::Value::Null, &serde_json::json!(9))
    );
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(html.contains(&format!("Failed:</strong> {why}")), "report.html");
    assert_eq!(s["reproducible"], false);
    assert!(
        s["reproducible_reasons"]
            .as_array()
            .unwrap()
            .iter()
            .any(|r| r.as_str().unwrap().contains("sent no exit report")),
        "killed with the run, the agents did not report: {}",
        s["reproducible_reasons"]
    );
}

/// The t of the last row of `telemetry.csv` as it stands.
fn simulated(dir: &Path) -> f64 {
    let text = std::fs::read_to_string(dir.join("telemetry.csv")).unwrap();
    let row = text.lines().rev().nth(1).unwrap();
    row.split(',').nth(1).unwrap().parse().unwrap()
}

/// A world or an agent stopped by a signal mid-run fails the run, and its summary says which
/// role and how, besides what the run left undone (it said `completed: false` and nothing else,
/// or, for an agent stopped near the end, `completed`). An agent told to stop steers no more:
/// it went on commanding for half a second of wall time (25 s of this run's simulated time).
#[test]
fn a_role_stopped_by_a_signal_mid_run_is_named_in_the_summary() {
    let _fleet = fleet();
    for (role, signal) in [("world", "-TERM"), ("agent", "-INT")] {
        let dir = scratch(&format!("stopped-{role}"));
        let mut launch = Launch::start(&paper("b-current"), &dir, &["--set", "mission.control_period=0.005"]);
        wait_until_simulated(&dir, 1.0);
        let pid = match role {
            "world" => world_pid(launch.child.id()),
            _ => agent_pid(&launch, 2),
        };
        kill(signal, pid);
        let signalled = simulated(&dir);
        let status = launch.wait(Duration::from_secs(60));
        assert_eq!(status.code(), Some(1), "{role}");
        let s = launch.summary();
        assert_eq!(s["completed"], false, "{s}");
        let why = failure(&s);
        eprintln!("{role} stopped at t ≈ {signalled} s: {why}");
        match role {
            "world" => assert!(why.starts_with("the world exited") && why.contains("130"), "{why}"),
            _ => {
                assert!(
                    why.starts_with("agent 2 exited with code 130 (stopped by a signal); see logs/agent-2.log"),
                    "{why}"
                );
                assert!(why.contains("vehicle 2 lost"), "{why}");
                let telemetry = std::fs::read_to_string(dir.join("telemetry.csv")).unwrap();
                let last_command = telemetry
                    .lines()
                    .skip(1)
                    .map(|l| l.split(',').collect::<Vec<_>>())
                    .filter(|r| r[2] == "2" && !r[6].is_empty())
                    .map(|r| r[1].parse::<f64>().unwrap())
                    .fold(0.0, f64::max);
                assert!(
                    last_command < signalled + 1.0,
                    "agent 2 steered to t = {last_command} s, signalled at t ≈ {signalled} s"
                );
            }
        }
        assert_none_left(&s);
    }
}

/// An agent gone before the first tick fails the run at once, in its own words: the world would
/// wait for it to its startup timeout (60 s), and the run say only that it did not start. The run
/// waits for a recorder that never comes, so no tick can come before the agent is killed.
#[test]
fn an_agent_gone_before_the_first_tick_fails_the_run_at_once() {
    let _fleet = fleet();
    let dir = scratch("agent-gone-early");
    let mut launch = Launch::start(&paper("b-current"), &dir, &["--recorders", "1"]);
    launch.wait_for("logs/agent-1.log", "path with t_f");
    kill("-9", agent_pid(&launch, 1));
    let status = launch.wait(Duration::from_secs(60));
    assert_eq!(status.code(), Some(1));
    let s = launch.summary();
    let why = failure(&s);
    assert!(
        why.starts_with("agent 1 exited (killed by signal 9) before the first tick"),
        "{why}"
    );
    assert_eq!(s["ticks"], 0);
    assert_none_left(&s);
}

/// In lockstep too the planner serves agents as they start: gone once the fleet runs, the run
/// goes on, says so, and is still the in-process run.
#[test]
fn a_lockstep_run_goes_on_without_its_planner_once_it_runs() {
    let _fleet = fleet();
    let dir = scratch("planner-gone-lockstep");
    let slow = ["--set", "mission.control_period=0.002", "--set", "comms.period=0.1"];
    let mut launch = Launch::start(&paper("b-current"), &dir.join("p"), &slow);
    wait_until_simulated(&dir.join("p"), 2.0);
    stop_the_planner(&launch);
    let s = went_on_without_its_planner(&mut launch, Duration::from_secs(120));
    run_in_process(&paper("b-current"), &dir.join("i"), &slow);
    assert_same_run(&dir.join("p"), &dir.join("i"));
    assert_none_left(&s);
}

/// Processes whose parent is gone, killed when the test ends however it ends.
struct Orphans(Vec<u32>);

impl Drop for Orphans {
    fn drop(&mut self) {
        for &pid in &self.0 {
            kill("-9", pid);
        }
    }
}

#[test]
fn no_child_outlives_a_launcher_killed_with_sigkill() {
    let _fleet = fleet();
    let dir = scratch("orphans");
    let mut launch = Launch::start(&paper("b-current"), &dir, &["--set", "mission.control_period=0.002"]);
    launch.wait_for("logs/world.log", "starting");
    let children = Orphans(descendants(launch.child.id()));
    assert!(children.0.len() >= 4, "planner, world and agents run: {:?}", children.0);
    kill("-9", launch.child.id());
    let _ = launch.child.wait();
    let deadline = Instant::now() + Duration::from_secs(3);
    while children.0.iter().any(|&pid| alive(pid)) {
        let left: Vec<u32> = children.0.iter().copied().filter(|&pid| alive(pid)).collect();
        assert!(
            Instant::now() < deadline,
            "children {left:?} outlived their launcher by 3 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The scheduling policy of `pid` (/proc/PID/stat, field 41): 0 SCHED_OTHER, 3 SCHED_BATCH.
fn policy(pid: u32) -> u32 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
    let rest: Vec<&str> = stat[stat.rfind(')').unwrap() + 2..].split(' ').collect();
    rest[41 - 3].parse().unwrap()
}

/// The binary is position-independent (ELF type DYN, a shared object), so that its image loads at
/// a random address: the build at a fixed address for a host of many agents is one a user opts
/// into (`cargo xtask fleet-build`), which `.ci/run` builds and checks apart.
#[test]
#[cfg(all(target_os = "linux", target_env = "gnu", not(target_feature = "crt-static")))]
fn the_binary_is_position_independent() {
    let readelf = Command::new("readelf")
        .args(["-h", env!("CARGO_BIN_EXE_tcpf")])
        .output()
        .expect("binutils' readelf reads the header");
    let header = String::from_utf8_lossy(&readelf.stdout);
    assert!(
        header.lines().any(|l| l.contains("Type:") && l.contains("DYN")),
        "{header}"
    );
}

#[test]
fn lockstep_agents_run_as_batch_jobs_and_realtime_agents_do_not() {
    let _fleet = fleet();
    let lockstep = ["--set", "mission.control_period=0.002"];
    let realtime = ["--clock", "realtime", "--time-scale", "10"];
    for (clock, agent) in [(&lockstep[..], 3), (&realtime[..], 0)] {
        let dir = scratch(&format!("policy-{agent}"));
        let mut launch = Launch::start(&paper("b-current"), &dir, clock);
        launch.wait_for("logs/world.log", "starting");
        // A tick's states all leave the world before the agents they wake take its CPU.
        assert_eq!(policy(agent_pid(&launch, 1)), agent, "{clock:?}");
        assert_eq!(policy(agent_pid(&launch, 2)), agent, "{clock:?}");
        assert_eq!(
            policy(world_pid(launch.child.id())),
            0,
            "the world keeps the usual policy"
        );
        kill("-INT", launch.child.id());
        launch.wait(Duration::from_secs(10));
    }
}

#[test]
fn sigint_stops_every_child_and_leaves_a_readable_run_directory() {
    let _fleet = fleet();
    let dir = scratch("sigint");
    // About 8 s of ticks, to be stopped a few hundred ticks in on any machine.
    let mut launch = Launch::start(&paper("b-current"), &dir, &["--set", "mission.control_period=0.001"]);
    wait_until_simulated(&dir, 0.3);
    let children = descendants(launch.child.id());
    assert!(children.len() >= 4, "planner, world and agents run: {children:?}");
    let signalled = Instant::now();
    kill("-INT", launch.child.id());
    let status = launch.wait(Duration::from_secs(10));
    let all_gone = Instant::now();
    assert_eq!(status.code(), Some(130));
    for pid in &children {
        assert!(!alive(*pid), "child {pid} survived");
    }
    assert!(
        all_gone - signalled < Duration::from_secs(2),
        "stopped in {:?}",
        all_gone - signalled
    );
    let s = launch.summary();
    assert_eq!(s["interrupted"], true);
    assert_eq!(s["completed"], false);
    // Told to stop, every child exited by itself (not killed: an exit code), having said what
    // it refused. Which code depends on what it heard first: the signal, or the world's end.
    for c in s["children"].as_array().unwrap() {
        assert!(c["exit_code"].is_i64(), "{c}");
        assert!(c["rejected"].is_u64(), "{c}");
    }
    let telemetry = std::fs::read_to_string(dir.join("telemetry.csv")).unwrap();
    let rows = telemetry.lines().count() as u64;
    assert_eq!(rows, 1 + 2 * s["ticks"].as_u64().unwrap(), "whole ticks only");
    assert!(rows > 1);
    toml::from_str::<toml::Table>(&std::fs::read_to_string(dir.join("mission.toml")).unwrap()).unwrap();
}

#[test]
fn a_run_whose_recorder_never_comes_says_who_is_missing() {
    let _fleet = fleet();
    let dir = scratch("missing-recorder");
    let mut launch = Launch::start(
        &paper("b-current"),
        &dir,
        &["--recorders", "1", "--startup-timeout", "2"],
    );
    let status = launch.wait(Duration::from_secs(30));
    assert_eq!(status.code(), Some(1));
    let mut stderr = String::new();
    std::io::Read::read_to_string(launch.child.stderr.as_mut().unwrap(), &mut stderr).unwrap();
    assert!(
        stderr.contains("the world exited (code 1) before the end: world: after 2s, 1 of 2 recorders still missing (logs/world.log)"),
        "{stderr}"
    );
    assert!(failure(&launch.summary()).contains("1 of 2 recorders still missing"));
}

/// The process group of `pid`, from /proc/PID/stat (the fifth field; the second, the command,
/// is in parentheses).
fn process_group(pid: u32) -> u32 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
    let after = &stat[stat.rfind(')').unwrap() + 2..];
    after.split(' ').nth(2).unwrap().parse().unwrap()
}

#[test]
fn a_terminals_ctrl_c_to_the_whole_job_is_an_interrupted_run() {
    let _fleet = fleet();
    // Half of such runs ended as completed, not arrived (exit 1) while the children were in the
    // launcher's group: the world, stopped by the same signal, sent its end first.
    for attempt in 0..4 {
        let dir = scratch(&format!("job-sigint-{attempt}"));
        let mut launch = Launch::start_as_a_job(&config("long3"), &dir, &[]);
        launch.wait_for("logs/world.log", "starting");
        std::thread::sleep(Duration::from_millis(200 + 150 * attempt));
        let children = descendants(launch.child.id());
        // The terminal's signal reaches the launcher alone, which tells every child.
        let job = process_group(launch.child.id());
        assert!(
            children.iter().all(|&pid| process_group(pid) != job),
            "a child is in the job's group"
        );
        let group = format!("-{}", launch.child.id());
        Command::new("kill").args(["-INT", "--", &group]).status().unwrap();
        let status = launch.wait(Duration::from_secs(10));
        assert_eq!(status.code(), Some(130), "attempt {attempt}");
        assert!(
            children.iter().all(|&pid| !alive(pid)),
            "attempt {attempt}: a child survived"
        );
        let s = launch.summary();
        assert_eq!(s["interrupted"], true, "attempt {attempt}");
        assert_eq!(s["completed"], false, "attempt {attempt}");
    }
}

/// Children started by a test, killed when it ends whatever happens.
struct Fleet(Vec<Child>);

impl Drop for Fleet {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// A role of the `tcpf` binary, its output dropped but for its standard error, when `stderr`
/// says so.
fn role(args: &[&str], stderr: Stdio) -> Child {
    Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args(credentialed(args))
        .stdout(Stdio::null())
        .stderr(stderr)
        .spawn()
        .unwrap()
}

/// The planner, a world that waits for one recorder and the agents `ids` of `mission`, started
/// by hand on a free loopback endpoint with the `clock` options (the world is the second, its
/// log `world.log` in `dir`), and that endpoint.
fn by_hand(mission: &str, ids: &[&str], clock: &[&str], dir: &Path) -> (Fleet, String) {
    let start = |args: &[&str]| role(&[args, clock].concat(), Stdio::null());
    let (planner, endpoint) = listening(|endpoint| start(&["planner", mission, "-l", endpoint]));
    let mut fleet = Fleet(vec![planner]);
    let world_log = std::fs::File::create(dir.join("world.log")).unwrap();
    let world = [&["world", mission, "-e", &endpoint, "--recorders", "1"], clock].concat();
    fleet.0.push(role(&world, Stdio::from(world_log)));
    for id in ids {
        fleet.0.push(start(&["agent", mission, "--id", id, "-e", &endpoint]));
    }
    (fleet, endpoint)
}

#[test]
fn roles_started_by_hand_demand_their_credential_and_make_the_same_run() {
    let _fleet = fleet();
    let dir = scratch("by-hand");
    let mission = paper("b-current");
    let (mut fleet, endpoint) = by_hand(&mission, &["2", "1"], &[], &dir);
    wait_for_text(&dir.join("world.log"), "(2 of 2)", Duration::from_secs(30));
    // A process without the fleet's credential reaches the port and hears nothing: the world,
    // which waits for a recorder, never meets it.
    let anonymous = dir.join("anonymous");
    let o = Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args(["record", &mission, "-e", &endpoint, "--open", "--startup-timeout", "5"])
        .args(["--out", anonymous.to_str().unwrap()])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{said}");
    assert!(said.contains("this role runs open (--open)"), "{said}");
    assert!(said.contains("no world of mission paper-b-current within 5s"), "{said}");
    assert!(!anonymous.exists(), "nothing recorded");
    let world = std::fs::read_to_string(dir.join("world.log")).unwrap();
    assert!(!world.contains("a recorder is here"), "{world}");
    let out = dir.join("p");
    let record = record_by_hand(&mission, &endpoint, &out).output().unwrap();
    assert!(record.status.success(), "{}", String::from_utf8_lossy(&record.stderr));
    for child in &mut fleet.0 {
        let deadline = Instant::now() + Duration::from_secs(10);
        while child.try_wait().unwrap().is_none() {
            assert!(Instant::now() < deadline, "a role did not exit after the end");
            std::thread::sleep(Duration::from_millis(20));
        }
        assert!(child.wait().unwrap().success());
    }
    run_in_process(&mission, &dir.join("i"), &[]);
    assert_same_run(&out, &dir.join("i"));
}

/// Two worlds and two agents of each vehicle started at once, every role a client of one router,
/// twenty times: each time exactly one world and one agent per vehicle drive the fleet, to the
/// same run as in-process, and the others exit 2 naming who holds their role. Before claims
/// (`tcpf_core::fleet::claim`), a role looked for a holder before it announced itself, and two that
/// started together could both find nobody.
#[test]
fn of_two_worlds_and_two_agents_per_vehicle_started_at_once_one_of_each_drives_the_fleet() {
    let _fleet = fleet();
    let dir = scratch("race");
    let mission = paper("b-current");
    run_in_process(&mission, &dir.join("i"), &[]);
    let (router, endpoint) = listening(|e| role(&["router", "-l", e], Stdio::null()));
    let _router = Reaper(router);
    for round in 0..20 {
        let at = dir.join(format!("round-{round}"));
        std::fs::create_dir_all(&at).unwrap();
        let log = |name: &str| Stdio::from(std::fs::File::create(at.join(name)).unwrap());
        let client =
            |args: &[&str], name: &str| role(&[args, &["-e", &endpoint, "--mode", "client"]].concat(), log(name));
        let mut contenders = Fleet(vec![
            client(&["world", &mission, "--recorders", "1"], "world-a.log"),
            client(&["world", &mission, "--recorders", "1"], "world-b.log"),
            client(&["agent", &mission, "--id", "1"], "agent-1a.log"),
            client(&["agent", &mission, "--id", "1"], "agent-1b.log"),
            client(&["agent", &mission, "--id", "2"], "agent-2a.log"),
            client(&["agent", &mission, "--id", "2"], "agent-2b.log"),
        ]);
        let _others = Fleet(vec![client(&["planner", &mission], "planner.log")]);
        let out = at.join("p");
        let record = record_by_hand(&mission, &endpoint, &out).output().unwrap();
        assert!(
            record.status.success(),
            "round {round}: {}",
            String::from_utf8_lossy(&record.stderr)
        );
        let mut codes = Vec::new();
        for (child, name) in contenders
            .0
            .iter_mut()
            .zip(["world-a", "world-b", "agent-1a", "agent-1b", "agent-2a", "agent-2b"])
        {
            let code = wait_exit(child, Duration::from_secs(30), name);
            let said = std::fs::read_to_string(at.join(format!("{name}.log"))).unwrap();
            if code == Some(2) {
                assert!(
                    said.contains("is already running, held by session"),
                    "round {round}, {name}: {said}"
                );
            } else {
                assert_eq!(code, Some(0), "round {round}, {name}: {said}");
            }
            codes.push(code);
        }
        for (pair, role) in codes.chunks(2).zip(["world", "agent 1", "agent 2"]) {
            let held = pair.iter().filter(|&&c| c == Some(0)).count();
            assert_eq!(
                held, 1,
                "round {round}: {held} processes held the {role}: exit codes {codes:?}"
            );
        }
        assert_same_run(&out, &dir.join("i"));
    }
}

/// A second agent of one vehicle, or a second world of one fleet, is refused (exit 2): both
/// would steer the same vehicles. Every role a client of one router, as on a testbed: the router
/// knows every token (peers that have not yet met every other peer may not).
/// Waits (30 s at most) until the router at `endpoint` knows every liveliness token ending in
/// one of `wanted`, asking it as a client.
fn router_knows(endpoint: &str, wanted: &[&str]) {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        let mut config = zenoh::Config::default();
        for (key, value) in [
            ("mode", "\"client\"".to_string()),
            ("connect/endpoints", format!("[\"{endpoint}\"]")),
            ("scouting/multicast/enabled", "false".to_string()),
            ("transport/auth/usrpwd", usrpwd()),
        ] {
            config.insert_json5(key, &value).unwrap();
        }
        let session = zenoh::open(config).await.unwrap();
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let known = common::tokens(&session, "tcpf/paper-b-current/alive/**").await;
            if wanted.iter().all(|w| known.iter().any(|k| k.ends_with(w))) {
                break;
            }
            assert!(Instant::now() < deadline, "the router knows only {known:?}");
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        session.close().await.unwrap();
    });
}

#[test]
fn a_second_agent_of_a_vehicle_or_a_second_world_is_refused() {
    let _fleet = fleet();
    let dir = scratch("second");
    let mission = paper("b-current");
    let (router, endpoint) = listening(|e| role(&["router", "-l", e], Stdio::null()));
    let _router = Reaper(router);
    let client = |args: &[&str], stderr: Stdio| role(&[args, &["-e", &endpoint, "--mode", "client"]].concat(), stderr);
    // Each role's log in the scratch directory, for a failure to be read.
    let log = |name: &str| Stdio::from(std::fs::File::create(dir.join(name)).unwrap());
    let _fleet = Fleet(vec![
        client(&["planner", &mission], log("planner.log")),
        client(&["world", &mission, "--recorders", "1"], log("world.log")),
        client(&["agent", &mission, "--id", "1"], log("agent-1.log")),
        client(&["agent", &mission, "--id", "2"], log("agent-2.log")),
    ]);
    // The world waits for its recorder: everyone else is there, nothing runs yet; and the router
    // knows every role's token (the world logs that it saw its agents before the declaration of
    // its own token has reached the router, and on a loaded machine a second world asked in
    // between).
    wait_for_text(&dir.join("world.log"), "(2 of 2)", Duration::from_secs(30));
    router_knows(&endpoint, &["alive/world/0", "alive/agent/1", "alive/agent/2"]);
    // Also when told, as `tcpf run` tells its own, that no other process claims the role now:
    // the holder's claim is at the router already, and that is decided at once.
    let mut second = Fleet(vec![
        client(&["agent", &mission, "--id", "2"], Stdio::piped()),
        client(&["world", &mission], Stdio::piped()),
        client(&["agent", &mission, "--id", "1", "--no-rivals"], Stdio::piped()),
        client(&["world", &mission, "--no-rivals"], Stdio::piped()),
    ]);
    for (n, words) in [
        "agent 2 of mission paper-b-current is already running",
        "a world of mission paper-b-current is already running",
        "agent 1 of mission paper-b-current is already running",
        "a world of mission paper-b-current is already running",
    ]
    .iter()
    .enumerate()
    {
        let (code, stderr) = exited(&mut second.0[n], Duration::from_secs(30), words);
        assert_eq!(code, Some(2), "{stderr}");
        assert!(stderr.contains(words), "{stderr}");
    }
}

/// A lockstep recorder writes nothing it could be refused for: one of another mission's
/// settings is refused by the world's clock before its first tick is written, and one that
/// comes when the run is under way says it came too late; both leave `--out` free.
#[test]
fn a_recorder_of_another_mission_or_too_late_writes_nothing() {
    let _fleet = fleet();
    let dir = scratch("recorder-refused");
    let mission = config("long3");
    let (_fleet, endpoint) = by_hand(&mission, &["1", "2", "3"], &[], &dir);
    let out = dir.join("other");
    let other = [
        "record",
        &mission,
        "-e",
        &endpoint,
        "--out",
        out.to_str().unwrap(),
        "--set",
        "comms.loss=0.1",
    ];
    let mut other = Fleet(vec![role(&other, Stdio::piped())]);
    let (code, stderr) = exited(
        &mut other.0[0],
        Duration::from_secs(30),
        "the recorder of another mission ran on",
    );
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("digest"), "{stderr}");
    assert!(!out.exists(), "nothing written: {stderr}");

    // A world that waits for no recorder, and one that comes once it runs.
    let late = dir.join("late");
    std::fs::create_dir_all(&late).unwrap();
    let (planner, endpoint) = listening(|e| role(&["planner", &mission, "-l", e], Stdio::null()));
    let world_log = std::fs::File::create(late.join("world.log")).unwrap();
    let mut fleet = Fleet(vec![
        planner,
        role(&["world", &mission, "-e", &endpoint], Stdio::from(world_log)),
    ]);
    for id in ["1", "2", "3"] {
        fleet
            .0
            .push(role(&["agent", &mission, "--id", id, "-e", &endpoint], Stdio::null()));
    }
    wait_for_text(&late.join("world.log"), "starting", Duration::from_secs(60));
    let out = late.join("p");
    fleet.0.push(role(
        &["record", &mission, "-e", &endpoint, "--out", out.to_str().unwrap()],
        Stdio::piped(),
    ));
    let recorder = fleet.0.last_mut().unwrap();
    let (code, stderr) = exited(recorder, Duration::from_secs(30), "the late recorder ran on");
    assert_ne!(code, Some(0), "{stderr}");
    assert!(stderr.contains("was under way when this recorder came"), "{stderr}");
    assert!(!out.exists(), "nothing written: {stderr}");
}

/// A new agent of a vehicle the world has lost (no `--rejoin-timeout`) is told so and stops:
/// its neighbours never wait for it again, and arrive.
#[test]
fn a_new_agent_of_a_lost_vehicle_is_told_and_the_others_arrive() {
    let _fleet = fleet();
    let dir = scratch("lost-again");
    let mission = config("long3");
    let (mut fleet, endpoint) = by_hand(&mission, &["1", "2", "3"], &[], &dir);
    let out = dir.join("r");
    let mut record = Reaper(
        record_by_hand(&mission, &endpoint, &out)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let world_log = dir.join("world.log");
    let logged = |what: &str| std::fs::read_to_string(&world_log).unwrap_or_default().contains(what);
    wait_for_text(&world_log, "starting", Duration::from_secs(30));
    let _ = fleet.0[3].kill();
    wait_for_text(&world_log, "agent 2 is gone at t = ", Duration::from_secs(30));
    let mut again = Reaper(role(&["agent", &mission, "--id", "2", "-e", &endpoint], Stdio::piped()));
    let (code, stderr) = exited(
        &mut again.0,
        Duration::from_secs(30),
        "the new agent of a lost vehicle ran on",
    );
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("the world gave up on this vehicle"), "{stderr}");
    assert!(logged("but the vehicle was lost at tick"));
    let deadline = Instant::now() + Duration::from_secs(120);
    while record.0.try_wait().unwrap().is_none() {
        assert!(Instant::now() < deadline, "the run did not end");
        std::thread::sleep(Duration::from_millis(20));
    }
    let s = summary(&out);
    let log = std::fs::read_to_string(&world_log).unwrap();
    assert_eq!(s["vehicles"][1]["lost"], true, "{s}\n{log}");
    for n in [0, 2] {
        assert!(
            s["vehicles"][n]["arrival_time"].as_f64().is_some(),
            "vehicle {} arrives: {s}",
            n + 1
        );
    }
}

/// A world that gives up at startup (a vehicle's agent never came) takes the agents that did
/// come with it: they stop, exit 1, rather than wait for a tick that will never come.
#[test]
fn agents_stop_when_the_world_gives_up_before_the_start() {
    let _fleet = fleet();
    let mission = paper("b-current");
    let (planner, endpoint) = listening(|e| role(&["planner", &mission, "-l", e], Stdio::null()));
    let mut fleet = Fleet(vec![planner]);
    // Agent 2 never comes; agent 1, started first so that it is there to see the world come
    // and go, waits for it longer than the world does.
    let agent = [
        "agent",
        &mission,
        "--id",
        "1",
        "-e",
        &endpoint,
        "--startup-timeout",
        "10",
    ];
    fleet.0.push(role(&agent, Stdio::piped()));
    let world = ["world", &mission, "-e", &endpoint, "--startup-timeout", "4"];
    fleet.0.push(role(&world, Stdio::null()));
    let (code, stderr) = exited(
        &mut fleet.0[1],
        Duration::from_secs(30),
        "agent 1 still waits for a world that gave up",
    );
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("is gone before the run started; stopping"), "{stderr}");
}

/// An agent started with another mission than the world's (here another `--set`) is refused
/// before its first command: it exits 2, and its vehicle is given up on at t = 0, never steered
/// by a law the run was not planned with.
#[test]
fn an_agent_of_another_mission_steers_nothing_before_it_is_refused() {
    let _fleet = fleet();
    let dir = scratch("other-mission");
    let mission = paper("b-current");
    let (planner, endpoint) = listening(|e| role(&["planner", &mission, "-l", e], Stdio::null()));
    let mut fleet = Fleet(vec![planner]);
    let world_log = std::fs::File::create(dir.join("world.log")).unwrap();
    fleet
        .0
        .push(role(&["world", &mission, "-e", &endpoint], Stdio::from(world_log)));
    fleet
        .0
        .push(role(&["agent", &mission, "--id", "1", "-e", &endpoint], Stdio::null()));
    let other = [
        "agent",
        &mission,
        "--id",
        "2",
        "-e",
        &endpoint,
        "--set",
        "control.kc=0.4",
    ];
    fleet.0.push(role(&other, Stdio::piped()));
    let (code, stderr) = exited(&mut fleet.0[3], Duration::from_secs(30), "agent 2 was never refused");
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("runs another mission than the world"), "{stderr}");
    let deadline = Instant::now() + Duration::from_secs(30);
    let log = loop {
        let log = std::fs::read_to_string(dir.join("world.log")).unwrap();
        if log.contains("agent 2 is gone at t = ") {
            break log;
        }
        assert!(Instant::now() < deadline, "the world never saw agent 2 go: {log}");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(log.contains("agent 2 is gone at t = 0.00 s"), "{log}");
}

/// `tcpf run --recorders 1` holds the run until another recorder has joined with the run
/// directory's Zenoh configuration; that recorder then records the same run, tick for tick.
#[test]
fn a_run_waits_for_a_recorder_from_elsewhere_which_records_the_same_run() {
    let _fleet = fleet();
    let dir = scratch("joined");
    let mission = paper("b-current");
    let mut launch = Launch::start(&mission, &dir.join("p"), &["--recorders", "1"]);
    launch.wait_for("endpoint", "tls/");
    launch.wait_for("logs/world.log", "a recorder is here (1 of 2)");
    // At the run's endpoint but without its credentials (its zenoh.json5): refused, and told so.
    let endpoint = std::fs::read_to_string(dir.join("p/endpoint")).unwrap();
    let refused = dir.join("refused");
    let o = Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args(["record", dir.join("p/mission.toml").to_str().unwrap()])
        .args([
            "-e",
            endpoint.trim(),
            "--mode",
            "client",
            "--open",
            "--out",
            refused.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{said}");
    assert!(said.contains("the router refused this process's credentials"), "{said}");
    assert!(!refused.exists(), "nothing recorded, nothing left");
    assert!(
        launch.child.try_wait().unwrap().is_none(),
        "the run went on without the recorder"
    );
    let telemetry = std::fs::read_to_string(dir.join("p/telemetry.csv")).unwrap_or_default();
    assert!(telemetry.lines().count() <= 1, "no tick before the recorder came");
    let joined = dir.join("joined");
    let record = Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args(["record", dir.join("p/mission.toml").to_str().unwrap()])
        .args(["-c", dir.join("p/zenoh.json5").to_str().unwrap()])
        .args(["--out", joined.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(record.status.success(), "{}", String::from_utf8_lossy(&record.stderr));
    assert!(launch.wait(Duration::from_secs(60)).success());
    run_in_process(&mission, &dir.join("i"), &[]);
    assert_same_run(&dir.join("p"), &dir.join("i"));
    assert_same_run(&joined, &dir.join("i"));
    assert_none_left(&launch.summary());
}

/// A recorder of a world that is killed before it announces the end: it says so within seconds,
/// writes the run directory (not completed) and exits 1, on either clock.
fn a_recorder_outlives_a_dead_world(name: &str, clock: &[&str]) {
    let dir = scratch(name);
    let mission = paper("b-current");
    // Agent 2 never comes, so the world waits for it until it is killed, and never says End.
    let (mut fleet, endpoint) = by_hand(&mission, &["1"], clock, &dir);
    let out = dir.join("p");
    let record = [
        &["record", &mission, "-e", &endpoint, "--out", out.to_str().unwrap()],
        clock,
    ]
    .concat();
    let log = dir.join("recorder.log");
    let mut recorder = Fleet(vec![role(&record, Stdio::from(std::fs::File::create(&log).unwrap()))]);
    // That the world met the recorder does not say the recorder met the world: its liveliness
    // history may come after the world's token went, with nothing in it, and a world it never saw
    // is one that never came (a startup timeout). Killed once it said so: should a late history
    // then bring the world back, it asks again and finds the world gone.
    wait_for_text(&log, "the world is here", Duration::from_secs(30));
    wait_for_text(&dir.join("world.log"), "agent 1 is here", Duration::from_secs(30));
    fleet.0[1].kill().unwrap();
    let code = wait_exit(
        &mut recorder.0[0],
        Duration::from_secs(30),
        "the recorder still waits for a dead world",
    );
    let stderr = std::fs::read_to_string(&log).unwrap();
    assert_eq!(code, Some(1), "{stderr}");
    if clock.is_empty() {
        // Waiting for the run to start, the lockstep agent gives the world's End its grace, and
        // stops without one: a failed run.
        let code = wait_exit(
            &mut fleet.0[2],
            Duration::from_secs(10),
            "agent 1 still waits for a dead world",
        );
        assert_eq!(code, Some(1));
    }
    assert!(stderr.contains("the world left without announcing the end"), "{stderr}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["completed"], false);
    assert_eq!(s["interrupted"], false);
    assert!(
        failure(&s).starts_with("the world left without announcing the end"),
        "{s}"
    );
    assert!(out.join("report.html").is_file());
}

#[test]
fn a_recorder_whose_world_dies_without_an_end_says_so_and_writes_the_run() {
    let _fleet = fleet();
    a_recorder_outlives_a_dead_world("world-dies", &[]);
}

#[test]
fn a_realtime_recorder_whose_world_dies_says_so_and_writes_the_run() {
    let _fleet = fleet();
    // The realtime recorder asks for the clock every 50 ms while the world has not started:
    // that must not keep the world's absence from counting.
    a_recorder_outlives_a_dead_world("world-dies-realtime", &["--clock", "realtime", "--time-scale", "10"]);
}

#[test]
fn roles_on_another_clock_than_the_worlds_refuse_to_run() {
    let _fleet = fleet();
    let mission = paper("b-current");
    let realtime = ["--clock", "realtime", "--time-scale", "10"];
    // A realtime world; agent 2 and the recorder left on the default lockstep clock. The world
    // has not started when they come, so they learn its clock only once it runs.
    let dir = scratch("wrong-clock");
    let (_fleet, endpoint) = by_hand(&mission, &["1"], &realtime, &dir);
    let out = dir.join("p");
    let mut late = Fleet(vec![
        role(&["agent", &mission, "--id", "2", "-e", &endpoint], Stdio::piped()),
        role(
            &["record", &mission, "-e", &endpoint, "--out", out.to_str().unwrap()],
            Stdio::piped(),
        ),
    ]);
    for (n, who) in ["agent", "recorder"].iter().enumerate() {
        let (code, stderr) = exited(
            &mut late.0[n],
            Duration::from_secs(30),
            &format!("the lockstep {who} still runs"),
        );
        assert_eq!(code, Some(2), "{stderr}");
        let why = format!("this {who} runs the lockstep clock but the world runs realtime");
        assert!(stderr.contains(&why), "{stderr}");
    }
    assert!(
        !out.exists(),
        "the refused recorder leaves --out free for the corrected command"
    );
    // A lockstep world (and its recorder), and a realtime agent.
    let second = dir.join("lockstep");
    std::fs::create_dir_all(&second).unwrap();
    let (_fleet, endpoint) = by_hand(&mission, &["1"], &[], &second);
    let out = second.join("p");
    let agent = role(
        &["agent", &mission, "--id", "2", "-e", &endpoint, "--clock", "realtime"],
        Stdio::piped(),
    );
    let recorder = role(
        &["record", &mission, "-e", &endpoint, "--out", out.to_str().unwrap()],
        Stdio::null(),
    );
    let mut late = Fleet(vec![agent, recorder]);
    let (code, stderr) = exited(&mut late.0[0], Duration::from_secs(30), "the realtime agent still runs");
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("this agent runs the realtime clock but the world runs lockstep"),
        "{stderr}"
    );
}

#[test]
fn a_sweep_of_real_fleets_matches_the_in_process_sweep() {
    let _fleet = fleet();
    let dir = scratch("sweep-processes");
    let sweep = |extra: &[&str], out: &Path| {
        let mut args = vec![
            "sweep",
            "--loss",
            "0,0.9",
            "--seeds",
            "1",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let mission = paper("d-lossy");
        args.insert(1, &mission);
        let o = Command::new(env!("CARGO_BIN_EXE_tcpf")).args(&args).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read_to_string(out.join("runs.csv")).unwrap()
    };
    let processes = sweep(&["--processes"], &dir.join("p"));
    assert_eq!(processes, sweep(&[], &dir.join("i")));
    assert!(
        dir.join("p/runs/0.9-seed1/report.html").is_file(),
        "each fleet keeps its run directory"
    );
}
