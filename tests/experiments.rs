//! Experiments as users run them: sweeps, fault models in mission files, and reports that a real
//! browser renders.

use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

mod common;
use common::{arrivals, config, fleet, kill, scratch, tcpf, Reaper};

fn ok(o: Output) -> Output {
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

fn json(file: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(file).unwrap()).unwrap()
}

#[test]
fn a_loss_sweep_of_case_d_grows_with_loss_and_matches_single_runs() {
    let _fleet = fleet();
    let dir = scratch("sweep");
    let out = dir.join("sweep");
    ok(tcpf(&[
        "sweep",
        &config("paper/d-lossy"),
        "--loss",
        "0,0.5,0.9",
        "--seeds",
        "20",
        "--out",
        out.to_str().unwrap(),
    ]));
    let summary = json(&out.join("sweep.json"));
    let means: Vec<f64> = summary["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["metrics"]["max_coordination_error"]["mean"].as_f64().unwrap())
        .collect();
    eprintln!("mean coordination error at loss 0, 0.5, 0.9: {means:?}");
    assert!(means[0] < means[1] && means[1] < means[2], "{means:?}");
    assert!((3.3..=4.3).contains(&means[2]), "MODEL §5 (d): {}", means[2]);
    for plot in [
        "sweep-error.svg",
        "sweep-error.pdf",
        "sweep-clearance.svg",
        "sweep.html",
    ] {
        assert!(out.join(plot).is_file(), "{plot}");
    }

    let header = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    assert_eq!(
        header.lines().next().unwrap(),
        "run,comms.loss,seed,status,max_coordination_error,rms_coordination_error,integral_coordination_error,\
         resync_time,min_clearance,arrival_spread,last_arrival,delivered_fraction,messages_per_vehicle_s"
    );
    let rows = common::csv_rows(&out.join("runs.csv"));
    assert_eq!(rows.len(), 60);
    let f = |r: &std::collections::BTreeMap<String, String>, k: &str| r[k].parse::<f64>().unwrap();
    // The json's mean is the csv's mean.
    let at_09: Vec<f64> = rows
        .iter()
        .filter(|r| r["comms.loss"] == "0.9")
        .map(|r| f(r, "max_coordination_error"))
        .collect();
    assert!((at_09.iter().sum::<f64>() / 20.0 - means[2]).abs() < 1e-12);
    // A row is the run of the same mission, loss and seed, to the bit.
    for (loss, seed) in [("0.5", "3"), ("0.9", "17")] {
        let row = rows
            .iter()
            .find(|r| r["comms.loss"] == loss && r["seed"] == seed)
            .unwrap();
        let run = dir.join(format!("run-{loss}-{seed}"));
        ok(tcpf(&[
            "run",
            &config("paper/d-lossy"),
            "--in-process",
            "--set",
            &format!("comms.loss={loss}"),
            "--seed",
            seed,
            "--out",
            run.to_str().unwrap(),
        ]));
        let s = json(&run.join("summary.json"));
        for key in [
            "max_coordination_error",
            "rms_coordination_error",
            "integral_coordination_error",
            "min_clearance",
        ] {
            assert_eq!(f(row, key), s[key].as_f64().unwrap(), "{key}");
        }
        let arrivals = arrivals(&s);
        assert_eq!(
            f(row, "arrival_spread"),
            arrivals.iter().copied().fold(f64::MIN, f64::max) - arrivals.iter().copied().fold(f64::MAX, f64::min)
        );
    }
}

#[test]
fn a_huge_sweep_streams_its_rows_in_bounded_memory_and_keeps_them_when_interrupted() {
    let _fleet = fleet();
    let out = scratch("sweep-huge").join("sweep");
    let mut sweep = Reaper(
        Command::new(env!("CARGO_BIN_EXE_tcpf"))
            .args(["sweep", &config("paper/d-lossy"), "--loss", "0,0.5"])
            .args(["--seeds", "1000000", "--out", out.to_str().unwrap()])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap(),
    );
    let csv = out.join("runs.csv");
    let lines = || std::fs::read_to_string(&csv).map_or(0, |s| s.lines().count());
    let started = std::time::Instant::now();
    while lines() < 200 {
        assert!(started.elapsed().as_secs() < 60, "rows reach runs.csv as runs finish");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let status = std::fs::read_to_string(format!("/proc/{}/status", sweep.0.id())).unwrap();
    let peak_kb: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|l| l.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap();
    kill("-INT", sweep.0.id());
    let status = sweep.0.wait().unwrap();
    let mut stdout = String::new();
    std::io::Read::read_to_string(sweep.0.stdout.as_mut().unwrap(), &mut stdout).unwrap();
    eprintln!("peak RSS of a sweep of 2 000 000 runs: {peak_kb} kB\n{stdout}");
    assert!(
        peak_kb < 100_000,
        "2 million runs planned, {peak_kb} kB: the grid is not held in memory"
    );
    assert_eq!(status.code(), Some(130), "an interrupted sweep exits 130");

    let summary = json(&out.join("sweep.json"));
    assert_eq!(summary["interrupted"], true);
    assert_eq!(summary["planned_runs"], 2_000_000);
    let done = summary["done_runs"].as_u64().unwrap();
    let text = std::fs::read_to_string(&csv).unwrap();
    let seeds: Vec<u64> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
        .collect();
    assert_eq!(
        seeds.len() as u64,
        done,
        "every finished run is in runs.csv, and only those"
    );
    assert!(seeds.iter().copied().eq(1..=done), "rows in grid order, none missing");
    assert_eq!(summary["points"][0]["runs"].as_u64(), Some(done));
    assert!(
        stdout.contains(&format!("interrupted: {done} of 2000000 runs done")),
        "{stdout}"
    );
}

#[test]
fn any_key_can_be_swept() {
    let _fleet = fleet();
    let dir = scratch("param");
    let o = ok(tcpf(&[
        "sweep",
        &config("paper/b-current"),
        "--param",
        "comms.delay=0,1.0",
        "--seeds",
        "2",
        "--out",
        dir.to_str().unwrap(),
    ]));
    assert!(String::from_utf8_lossy(&o.stdout).contains("comms.delay"));
    let csv = std::fs::read_to_string(dir.join("runs.csv")).unwrap();
    assert!(csv.starts_with("run,comms.delay,seed,status,"));
    assert_eq!(csv.lines().count(), 1 + 4);
    let o = tcpf(&[
        "sweep",
        &config("paper/b-current"),
        "--param",
        "comms.dealy=0,1",
        "--seeds",
        "1",
        "--out",
        dir.join("typo").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "a typo in the swept key is bad input");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("--param comms.dealy=0,1 (the value 0): unknown field `dealy`") && !stderr.contains("--set"),
        "the sweep's flag is named: {stderr}"
    );
}

#[test]
fn a_threshold_sweep_shows_messages_traded_for_coordination() {
    let _fleet = fleet();
    let dir = scratch("threshold");
    let o = ok(tcpf(&[
        "sweep",
        &config("paper/b-current"),
        "--param",
        "comms.threshold=0,0.02,0.5",
        "--set",
        "comms.trigger=event",
        "--seeds",
        "1",
        "--out",
        dir.to_str().unwrap(),
    ]));
    print!("{}", String::from_utf8_lossy(&o.stdout));
    let rows = common::csv_rows(&dir.join("runs.csv"));
    let get = |r: &std::collections::BTreeMap<String, String>, k: &str| r[k].parse::<f64>().unwrap();
    let error = |r: &std::collections::BTreeMap<String, String>| get(r, "max_coordination_error");
    let rate = |r: &std::collections::BTreeMap<String, String>| get(r, "messages_per_vehicle_s");
    let last = |r: &std::collections::BTreeMap<String, String>| get(r, "last_arrival");
    // docs/LINKS.md, to the places it prints: δ = 0 sends at every instant (10 a second), as
    // periodic sending does; 0.02 s cuts that twentyfold at the same error; 0.5 s costs
    // coordination, and moves the arrival.
    let printed = |x: f64, figure: f64| (x - figure).abs() <= 0.005 + 1e-9;
    for (row, (r, e, a)) in rows
        .iter()
        .zip([(10.0, 0.36, 55.47), (0.54, 0.36, 55.44), (0.21, 0.56, 52.68)])
    {
        assert!(
            printed(rate(row), r) && printed(error(row), e) && printed(last(row), a),
            "threshold {}: {} broadcasts per vehicle and second, error {} s, last arrival {} s",
            row["comms.threshold"],
            rate(row),
            error(row),
            last(row)
        );
    }
    let arrival = std::fs::read_to_string(dir.join("sweep-arrival.svg")).unwrap();
    assert!(arrival.contains("last arrival (s)"), "the arrival is plotted too");
    let plot = std::fs::read_to_string(dir.join("sweep-messages.svg")).unwrap();
    assert!(plot.contains("broadcasts per vehicle per second"));
}

/// Debian's chromium, headless, as the machine's notes prescribe for a closed network.
fn chromium(args: &[&str]) -> Output {
    let profile = scratch("chromium-profile");
    let exe = ["chromium", "/usr/bin/chromium"]
        .into_iter()
        .find(|c| Command::new(c).arg("--version").output().is_ok());
    let exe = exe.expect("this test needs Debian's chromium: apt-get install chromium (scripts/test installs it)");
    Command::new(exe)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            &format!("--user-data-dir={}", profile.display()),
        ])
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn the_report_renders_in_a_real_browser_with_every_plot() {
    let _fleet = fleet();
    let dir = scratch("report");
    let run = dir.join("run");
    ok(tcpf(&[
        "run",
        &config("outage"),
        "--in-process",
        "--out",
        run.to_str().unwrap(),
    ]));
    let page = format!("file://{}", run.join("report.html").display());
    let dom = chromium(&["--dump-dom", &page]);
    let dom = String::from_utf8_lossy(&dom.stdout).to_string();
    for id in [
        "paths",
        "coordination",
        "distances",
        "speeds",
        "cross-track",
        "links",
        "messages",
        "receptions",
    ] {
        let start = dom
            .find(&format!("id=\"{id}\""))
            .unwrap_or_else(|| panic!("figure {id} missing from the rendered page"));
        let figure = &dom[start..start + dom[start..].find("</figure>").unwrap()];
        assert!(figure.contains("<svg"), "{id}: no svg");
        let marks =
            figure.matches("<polyline").count() + figure.matches("<rect").count() + figure.matches("<circle").count();
        assert!(marks > 2, "{id}: empty plot");
    }
    assert!(dom.contains("id=\"summary\""));
    let shot = dir.join("report.png");
    let o = chromium(&[
        "--window-size=1000,2600",
        &format!("--screenshot={}", shot.display()),
        &page,
    ]);
    let size = std::fs::metadata(&shot).map(|m| m.len()).unwrap_or(0);
    assert!(
        size > 50_000,
        "a screenshot with something on it ({size} bytes): {}",
        String::from_utf8_lossy(&o.stderr)
    );
    // `tcpf report` regenerates the same page from the recorded files.
    let before = std::fs::read(run.join("report.html")).unwrap();
    std::fs::remove_file(run.join("report.html")).unwrap();
    ok(tcpf(&["report", run.to_str().unwrap()]));
    assert_eq!(std::fs::read(run.join("report.html")).unwrap(), before);
}

#[test]
fn contradictory_fault_settings_are_bad_input() {
    let _fleet = fleet();
    let o = tcpf(&["plan", &config("outage"), "--set", "comms.delay=-1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("comms.delay"));
}

/// What a sweep cannot average it says: runs in which a vehicle never arrived are counted, and
/// their spread and last arrival left out, in the table and sweep.json; a swept key that changes
/// nothing and values that cannot be plotted are named. An infeasible value fails the sweep
/// before anything is written.
#[test]
fn a_sweep_says_what_it_could_not_average() {
    let _fleet = fleet();
    let dir = scratch("sweep-says");
    let short = dir.join("short");
    let o = ok(tcpf(&[
        "sweep",
        &config("paper/d-lossy"),
        "--loss",
        "0,0.9",
        "--set",
        "mission.max_duration=57.5",
        "--seeds",
        "10",
        "--out",
        short.to_str().unwrap(),
    ]));
    let printed = String::from_utf8_lossy(&o.stdout);
    let summary = json(&short.join("sweep.json"));
    let (all, lossy) = (&summary["points"][0], &summary["points"][1]);
    assert_eq!((all["runs"].as_u64(), all["arrived"].as_u64()), (Some(10), Some(10)));
    let arrived = lossy["arrived"].as_u64().unwrap();
    assert!(
        (1..10).contains(&arrived),
        "at loss 0.9 some runs do not arrive in 57.5 s: {arrived}"
    );
    assert!(
        printed.contains(&format!(
            "comms.loss = 0.9: in {} of 10 runs a vehicle never arrived",
            10 - arrived
        )),
        "{printed}"
    );
    let last = all["metrics"]["last_arrival"]["mean"].as_f64().unwrap();
    assert!(
        (last - 55.467).abs() < 0.01,
        "without loss, case (d)'s fleet arrives as case (b)'s, at 55.467 s: {last}"
    );

    let idle = dir.join("idle");
    let o = ok(tcpf(&[
        "sweep",
        &config("paper/b-current"),
        "--param",
        "comms.threshold=0,0.5",
        "--seeds",
        "1",
        "--out",
        idle.to_str().unwrap(),
    ]));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("every value of comms.threshold gave the same results"),
        "periodic sending has no threshold"
    );
    let words = dir.join("words");
    ok(tcpf(&[
        "sweep",
        &config("paper/b-current"),
        "--param",
        "comms.trigger=periodic,event",
        "--seeds",
        "1",
        "--out",
        words.to_str().unwrap(),
    ]));
    let bars = std::fs::read_to_string(words.join("sweep-error.svg")).unwrap();
    assert!(
        bars.contains("<rect") && bars.contains("\nperiodic\n") && bars.contains("\nevent\n"),
        "a bar per value"
    );

    let infeasible = dir.join("infeasible");
    let o = tcpf(&[
        "sweep",
        &config("paper/a-nominal"),
        "--param",
        "planner.clearance=1,4",
        "--seeds",
        "1",
        "--out",
        infeasible.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("planner.clearance = 4: infeasible plan"));
    assert!(
        !infeasible.exists(),
        "nothing written, so the same --out can be used again"
    );
}

/// Bursty loss on a mission file without a `[comms.burst]` table: one of its keys swept, the
/// other set, the table is whole only with both, in every run.
#[test]
fn a_table_absent_from_the_file_can_be_swept_key_by_key() {
    let _fleet = fleet();
    let dir = scratch("sweep-burst");
    ok(tcpf(&[
        "sweep",
        &config("paper/b-current"),
        "--param",
        "comms.burst.p_enter_bad=0.02,0.1",
        "--set",
        "comms.burst.p_leave_bad=0.2",
        "--seeds",
        "2",
        "--out",
        dir.to_str().unwrap(),
    ]));
    let summary = json(&dir.join("sweep.json"));
    let delivered: Vec<f64> = summary["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["metrics"]["delivered_fraction"]["mean"].as_f64().unwrap())
        .collect();
    assert!(
        delivered[0] > delivered[1],
        "longer bad spells lose more: {delivered:?}"
    );
}

/// One value is one point, and a line through one point draws nothing: it is marked.
#[test]
fn a_sweep_of_one_value_plots_its_point() {
    let _fleet = fleet();
    let dir = scratch("sweep-one");
    ok(tcpf(&[
        "sweep",
        &config("paper/b-current"),
        "--loss",
        "0.5",
        "--seeds",
        "1",
        "--out",
        dir.to_str().unwrap(),
    ]));
    let svg = std::fs::read_to_string(dir.join("sweep-error.svg")).unwrap();
    assert!(svg.contains("<circle"), "the mean at loss 0.5 is marked");
    assert!(svg.contains("mean of 1 seed\n"), "one seed, singular");
}

/// A sweep's directory says what made it: the mission of its first value (`mission.toml`, the
/// `--set`s applied), and in sweep.json the command, tcpf's version and the mission's digest.
#[test]
fn a_sweeps_directory_says_what_made_it() {
    let dir = scratch("sweep-provenance");
    let args = [
        "sweep",
        &config("paper/a-nominal"),
        "--loss",
        "0,0.1",
        "--seeds",
        "1",
        "--set",
        "control.kc=0.4",
        "--out",
        dir.to_str().unwrap(),
    ];
    ok(tcpf(&args));
    let as_run = std::fs::read_to_string(dir.join("mission.toml")).unwrap();
    let (said, toml) = as_run.split_once('\n').unwrap();
    assert_eq!(
        said,
        "# The mission of the sweep's first grid point, comms.loss = 0; sweep.json has the grid."
    );
    assert!(toml.contains("kc = 0.4") && toml.contains("loss = 0.0"), "{toml}");
    common::assert_provenance(&json(&dir.join("sweep.json"))["provenance"], &args, toml);
}
