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
         resync_time,min_clearance,arrival_spread,last_arrival,delivered_fraction,messages_per_vehicle_s,\
         frames_delivered,frames_busy,frames_half_duplex,frames_collision,frames_noise,frames_loss,frames_burst,\
         frames_outage,frames_range"
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
    // A list is one value: two starts of vehicle 1, two grid points.
    let starts = dir.join("starts");
    ok(tcpf(&[
        "sweep",
        &config("paper/b-current"),
        "--param",
        "vehicle.1.start=[0,0],[0,1]",
        "--seeds",
        "1",
        "--out",
        starts.to_str().unwrap(),
    ]));
    let rows = common::csv_rows(&starts.join("runs.csv"));
    let values: Vec<&str> = rows.iter().map(|r| r["vehicle.1.start"].as_str()).collect();
    assert_eq!(values, ["[0,0]", "[0,1]"]);
    assert_ne!(rows[0]["min_clearance"], rows[1]["min_clearance"], "the start moved");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("--param comms.dealy (the value 0): unknown field `dealy`") && !stderr.contains("--set"),
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
    assert!(plot.contains("γ broadcasts per vehicle (1/s)"));
}

/// Debian's chromium, headless, as the machine's notes prescribe for a closed network.
fn chromium(args: &[&str]) -> Output {
    // A profile per browser: two at once on one profile, the second aborts.
    static BROWSERS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let n = BROWSERS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let profile = scratch(&format!("chromium-profile-{n}"));
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
    // Each fate of a message in a lane of its own in each link's row: dots of one colour at
    // one height per link, and no height shared by two colours (one painted over another would
    // hide how many there were). A legend's dot is alone at its height.
    let raster = std::fs::read_to_string(run.join("figures/receptions.svg")).unwrap();
    let mut lanes: std::collections::BTreeMap<(String, String), usize> = Default::default();
    for circle in raster.split("<circle").skip(1) {
        let attr = |name: &str| {
            let at = circle.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
            circle[at..at + circle[at..].find('"').unwrap()].to_string()
        };
        *lanes.entry((attr("fill"), attr("cy"))).or_default() += 1;
    }
    lanes.retain(|_, dots| *dots > 1);
    let colours: std::collections::BTreeSet<&String> = lanes.keys().map(|(fill, _)| fill).collect();
    assert!(colours.len() >= 2, "delivered and lost in the outage: {lanes:?}");
    for colour in &colours {
        let heights = lanes.keys().filter(|(fill, _)| fill == *colour).count();
        assert_eq!(heights, 2, "{colour}: one lane in each of the two links: {lanes:?}");
    }
    let heights: std::collections::BTreeSet<&String> = lanes.keys().map(|(_, cy)| cy).collect();
    assert_eq!(heights.len(), lanes.len(), "a lane per colour and link: {lanes:?}");
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
    for figure in ["sweep-error", "sweep-messages"] {
        let bars = std::fs::read_to_string(words.join(format!("{figure}.svg"))).unwrap();
        assert!(
            bars.contains("<rect") && bars.contains("\nperiodic\n") && bars.contains("\nevent\n"),
            "{figure}: a bar per value"
        );
    }

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
    assert!(svg.contains("<polygon opacity=\"1\""), "the mean at loss 0.5 is marked");
    assert!(svg.contains("mean of 1 seed\n"), "one seed, singular");
}

/// aggregate.tex compiles with plain pdflatex (Debian's texlive-latex-base and
/// texlive-latex-recommended, which scripts/test installs), and its table says what aggregate.csv
/// says: each mean and interval is the csv's, rounded to the decimals the table writes.
#[test]
fn aggregate_tex_compiles_with_pdflatex_and_says_what_aggregate_csv_says() {
    let dir = scratch("sweep-tex");
    {
        let _fleet = fleet();
        ok(tcpf(&[
            "sweep",
            &config("paper/b-current"),
            "--param",
            "comms.loss=0,0.5",
            "--seeds",
            "3",
            "--out",
            dir.to_str().unwrap(),
        ]));
    }
    let o = match Command::new("pdflatex")
        .args(["-interaction=nonstopmode", "-halt-on-error", "aggregate.tex"])
        .current_dir(&dir)
        .stdin(std::process::Stdio::null())
        .output()
    {
        Ok(o) => o,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            panic!(
                "pdflatex missing: run scripts/test, which installs texlive-latex-base and texlive-latex-recommended"
            )
        }
        Err(e) => panic!("pdflatex: {e}"),
    };
    if !o.status.success() {
        let log = std::fs::read_to_string(dir.join("aggregate.log"))
            .unwrap_or_else(|_| String::from_utf8_lossy(&o.stdout).into_owned());
        let lines: Vec<&str> = log.lines().collect();
        panic!(
            "pdflatex aggregate.tex in {} failed ({}); the end of its log:\n{}",
            dir.display(),
            o.status,
            lines[lines.len().saturating_sub(40)..].join("\n")
        );
    }
    assert!(std::fs::read(dir.join("aggregate.pdf")).unwrap().starts_with(b"%PDF-"));
    let document = std::fs::read_to_string(dir.join("aggregate.tex")).unwrap();
    assert!(document.contains("over 3 seeds"), "{document}");

    // The tabular: its header's words, then a row per grid point, cells split on &.
    let table = std::fs::read_to_string(dir.join("aggregate-table.tex")).unwrap();
    let (head, body) = table.split_once("\\midrule").expect("a booktabs tabular");
    let head = head.split_once("\\toprule").expect("a booktabs tabular").1;
    let body = body.split_once("\\bottomrule").expect("a booktabs tabular").0;
    // A header cell's words: the cell, or what its \parbox holds after \raggedleft.
    let words = |cell: &str| -> String {
        let cell = cell.trim();
        cell.strip_prefix("\\parbox")
            .and_then(|boxed| boxed.rsplit_once("\\ragged"))
            .and_then(|(_, w)| w.split_once(' '))
            .and_then(|(_, w)| w.strip_suffix('}'))
            .unwrap_or(cell)
            .to_string()
    };
    let heads: Vec<String> = head.trim().trim_end_matches("\\\\").split('&').map(words).collect();
    let rows: Vec<Vec<&str>> = body
        .split("\\\\")
        .map(str::trim)
        .filter(|r| !r.is_empty())
        .map(|r| r.split('&').map(str::trim).collect())
        .collect();
    let aggregate = common::csv_rows(&dir.join("aggregate.csv"));
    assert_eq!(rows.len(), aggregate.len(), "a row per grid point: {table}");
    for (row, a) in rows.iter().zip(&aggregate) {
        assert_eq!(row.len(), heads.len(), "{table}");
        assert_eq!(
            (row[0], row[1]),
            (a["comms.loss"].as_str(), a["runs"].as_str()),
            "{table}"
        );
        for (metric, label) in [
            ("max_coordination_error", "coordination error (s)"),
            ("last_arrival", "last arrival (s)"),
        ] {
            let column = heads
                .iter()
                .position(|h| h == label)
                .unwrap_or_else(|| panic!("no column {label}: {heads:?}"));
            let cell = row[column];
            let (mean, ci) = cell
                .trim_matches('$')
                .split_once("\\pm")
                .unwrap_or_else(|| panic!("{cell}: mean ± interval, with 3 seeds"));
            let (mean, ci) = (mean.trim(), ci.trim());
            let decimals = |x: &str| x.split_once('.').map_or(0, |(_, d)| d.len());
            assert_eq!(
                decimals(mean),
                decimals(ci),
                "{cell}: the mean to its interval's decimals"
            );
            let half = 0.5 * 10f64.powi(-(decimals(mean) as i32));
            for (tex, stat) in [(mean, "mean"), (ci, "ci95")] {
                let csv: f64 = a[&format!("{metric}_{stat}")].parse().unwrap();
                let tex: f64 = tex.parse().unwrap();
                assert!(
                    (tex - csv).abs() <= half * (1.0 + 1e-9),
                    "{metric}_{stat} at comms.loss = {}: {tex} in aggregate-table.tex, {csv} in aggregate.csv",
                    a["comms.loss"]
                );
            }
        }
    }
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

/// The grid of the fault study every test below runs: loss × delay × 5 seeds, case (b).
const GRID: [&str; 8] = [
    "--loss",
    "0,0.3,0.6",
    "--param",
    "comms.delay=0,1",
    "--seeds",
    "5",
    "--seed-start",
    "1",
];

/// `tcpf sweep` of case (b) over `GRID` with `extra` flags into `out`.
fn grid_sweep(out: &Path, extra: &[&str]) -> Output {
    let mission = config("paper/b-current");
    let mut args = vec!["sweep", mission.as_str()];
    args.extend(GRID);
    args.extend(extra);
    args.extend(["--out", out.to_str().unwrap()]);
    ok(tcpf(&args))
}

/// The tables of a sweep's directory, which every way of running the sweep must write alike.
fn tables(dir: &Path) -> (Vec<u8>, Vec<u8>) {
    (
        std::fs::read(dir.join("runs.csv")).unwrap(),
        std::fs::read(dir.join("aggregate.csv")).unwrap(),
    )
}

/// `tcpf sweep merge` of `shards` into `out`.
fn merge(shards: &[std::path::PathBuf], out: &Path) -> Output {
    let mut args = vec!["sweep".to_string(), "merge".into()];
    args.extend(shards.iter().map(|s| s.display().to_string()));
    args.extend(["--out".into(), out.display().to_string()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    ok(tcpf(&args))
}

/// A 3 × 2 × 5 study is one command: 30 rows, 6 aggregate rows, one curve per delay, and a
/// directory that says what made it and makes it again from its own files.
#[test]
fn a_grid_of_loss_by_delay_by_seeds_is_one_command_that_runs_again_from_its_own_files() {
    let dir = scratch("grid");
    let out = dir.join("sweep");
    let o = grid_sweep(&out, &[]);
    let printed = String::from_utf8_lossy(&o.stdout);
    let rows = common::csv_rows(&out.join("runs.csv"));
    assert_eq!(rows.len(), 30);
    let keys: Vec<(&str, &str, &str)> = rows
        .iter()
        .map(|r| (r["comms.loss"].as_str(), r["comms.delay"].as_str(), r["seed"].as_str()))
        .collect();
    assert_eq!(keys[0], ("0", "0", "1"));
    assert_eq!(
        keys[7],
        ("0", "1", "3"),
        "the last key fastest, each point through its seeds"
    );
    assert_eq!(keys[29], ("0.6", "1", "5"));
    assert!(rows.iter().all(|r| r["status"] == "arrived"));
    let aggregate = common::csv_rows(&out.join("aggregate.csv"));
    assert_eq!(aggregate.len(), 6);
    // Each aggregate row is the statistics of its five rows.
    for a in &aggregate {
        let errors: Vec<f64> = rows
            .iter()
            .filter(|r| r["comms.loss"] == a["comms.loss"] && r["comms.delay"] == a["comms.delay"])
            .map(|r| r["max_coordination_error"].parse().unwrap())
            .collect();
        let n = errors.len() as f64;
        let mean = errors.iter().sum::<f64>() / n;
        let sd = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let got = |k: &str| a[&format!("max_coordination_error_{k}")].parse::<f64>().unwrap();
        assert_eq!((a["runs"].as_str(), got("n")), ("5", 5.0));
        assert!(
            (got("mean") - mean).abs() < 1e-12 && (got("sd") - sd).abs() < 1e-12,
            "{a:?}"
        );
        // t(0.975, 4) = 2.776.
        assert!(
            (got("ci95") - 2.776 * sd / 5f64.sqrt()).abs() < 1e-3 * sd.max(1e-9),
            "{a:?}"
        );
    }
    // Loss costs coordination; a compensated delay of 1 s barely does (MODEL §6).
    let mean = |loss: &str, delay: &str| -> f64 {
        let a = aggregate
            .iter()
            .find(|a| a["comms.loss"] == loss && a["comms.delay"] == delay)
            .unwrap();
        a["max_coordination_error_mean"].parse().unwrap()
    };
    assert!((mean("0", "0") - 0.362).abs() < 0.001 && mean("0.6", "0") > 2.0 * mean("0", "0"));
    assert!((mean("0", "1") - 0.356).abs() < 0.001);
    // One curve per delay, a marker at each sampled loss, SVG and PDF.
    let svg = std::fs::read_to_string(out.join("sweep-error.svg")).unwrap();
    assert!(svg.contains("\ndelay 0 s\n") && svg.contains("\ndelay 1 s\n"), "{svg}");
    assert_eq!(
        svg.matches("<polygon opacity=\"1\"").count(),
        6 + 2,
        "6 means and 2 legend markers"
    );
    assert!(std::fs::read(out.join("sweep-error.pdf"))
        .unwrap()
        .starts_with(b"%PDF-"));
    let clearance = std::fs::read_to_string(out.join("sweep-clearance.svg")).unwrap();
    assert!(clearance.contains("required clearance E = 1 m"), "the requirement line");
    // Provenance: the mission as run, the command, the version.
    let summary = json(&out.join("sweep.json"));
    let toml = std::fs::read_to_string(out.join("mission.toml")).unwrap();
    let (_, toml) = toml.split_once('\n').unwrap();
    let mission = config("paper/b-current");
    let mut args = vec!["sweep", mission.as_str()];
    args.extend(GRID);
    args.extend(["--out", out.to_str().unwrap()]);
    common::assert_provenance(&summary["provenance"], &args, toml);
    // Made again from its own files, by the command it printed.
    let rerun = std::fs::read_to_string(out.join("rerun.sh")).unwrap();
    assert!(
        printed.contains(&format!("again: {}/rerun.sh DIR", out.display())),
        "{printed}"
    );
    assert!(rerun.contains("--param comms.loss=0,0.3,0.6 --param comms.delay=0,1 --seeds 5 --seed-start 1"));
    let again = dir.join("again");
    let o = Command::new(out.join("rerun.sh"))
        .arg(&again)
        .env("TCPF", env!("CARGO_BIN_EXE_tcpf"))
        .output()
        .unwrap();
    ok(o);
    assert!(tables(&again) == tables(&out), "the same runs.csv and aggregate.csv");
    assert_eq!(
        std::fs::read(again.join("mission.toml")).unwrap(),
        std::fs::read(out.join("mission.toml")).unwrap()
    );
}

/// Shards are the sweep: 1, 3 or 7 of them, merged, write its tables byte for byte; a shard
/// lost and run again with --resume, or one cut short, comes back.
#[test]
fn shards_merged_are_the_sweep_and_a_lost_shard_comes_back_with_resume() {
    let dir = scratch("shards");
    let whole = dir.join("whole");
    grid_sweep(&whole, &[]);
    for k in [1, 3, 7] {
        let shards: Vec<_> = (1..=k).map(|i| dir.join(format!("k{k}/shard-{i}"))).collect();
        for (i, shard) in shards.iter().enumerate() {
            grid_sweep(shard, &["--shard", &format!("{}/{k}", i + 1)]);
        }
        let rows: usize = shards.iter().map(|s| common::csv_rows(&s.join("runs.csv")).len()).sum();
        assert_eq!(rows, 30, "each run in one shard");
        let merged = dir.join(format!("k{k}/merged"));
        merge(&shards, &merged);
        assert!(tables(&merged) == tables(&whole), "{k} shards merged");
        if k == 3 {
            // The merge refuses what is not whole, and says how to make it whole.
            let o = tcpf(&[
                "sweep",
                "merge",
                shards[0].to_str().unwrap(),
                shards[2].to_str().unwrap(),
                "--out",
                dir.join("k3/partial").to_str().unwrap(),
            ]);
            assert_eq!(o.status.code(), Some(2));
            let said = String::from_utf8_lossy(&o.stderr);
            assert!(
                said.contains("10 of the sweep's 30 runs are in none of these directories (the first: run 1, comms.loss = 0, comms.delay = 0, seed 2)")
                    && said.contains("--resume"),
                "{said}"
            );
        }
        if k == 7 {
            // Shard 4 lost: rerun with --resume into its directory.
            std::fs::remove_dir_all(&shards[3]).unwrap();
            grid_sweep(&shards[3], &["--shard", "4/7", "--resume"]);
            // Shard 6 cut short: two of its rows gone.
            let csv = std::fs::read_to_string(shards[5].join("runs.csv")).unwrap();
            let kept: Vec<&str> = csv
                .lines()
                .enumerate()
                .filter(|(n, _)| *n != 2 && *n != 4)
                .map(|(_, l)| l)
                .collect();
            std::fs::write(shards[5].join("runs.csv"), kept.join("\n") + "\n").unwrap();
            let o = grid_sweep(&shards[5], &["--shard", "6/7", "--resume"]);
            assert!(String::from_utf8_lossy(&o.stdout).contains("sweep directory"));
            let merged = dir.join("k7/merged-again");
            merge(&shards, &merged);
            assert!(tables(&merged) == tables(&whole), "7 shards, two of them resumed");
        }
    }
    // --resume of another sweep's directory is refused, and nothing in it changes.
    let before = tables(&whole);
    let mission = config("paper/b-current");
    let o = tcpf(&[
        "sweep",
        &mission,
        "--loss",
        "0,0.3",
        "--seeds",
        "5",
        "--resume",
        "--out",
        whole.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("it holds another sweep"));
    assert!(tables(&whole) == before);
}

/// `tcpf sweep merge` takes nothing it cannot vouch for: a cell no run writes (NaN), a run done
/// in two of the directories, a shard holding another shard's rows, a mission.toml edited since
/// the sweep ran; each is refused by name (exit 2), and the shards as they were merge.
#[test]
fn a_merge_refuses_rows_and_missions_it_cannot_vouch_for() {
    let dir = scratch("merge-refuses");
    let shards: Vec<_> = (1..=2).map(|i| dir.join(format!("shard-{i}"))).collect();
    for (i, shard) in shards.iter().enumerate() {
        grid_sweep(shard, &["--shard", &format!("{}/2", i + 1)]);
    }
    let copy = |from: &Path, name: &str| {
        let to = dir.join(name);
        std::fs::create_dir_all(&to).unwrap();
        for file in ["sweep.json", "runs.csv", "mission.toml"] {
            std::fs::copy(from.join(file), to.join(file)).unwrap();
        }
        to
    };
    let refused = |dirs: &[&Path], words: &str| {
        let mut args = vec!["sweep".to_string(), "merge".into()];
        args.extend(dirs.iter().map(|d| d.display().to_string()));
        args.extend(["--out".into(), dir.join("merged-refused").display().to_string()]);
        let o = tcpf(&args.iter().map(String::as_str).collect::<Vec<_>>());
        let said = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{words}: {said}");
        assert!(said.contains(words), "{said}");
        assert!(!dir.join("merged-refused").exists(), "nothing written");
    };
    let nan = copy(&shards[0], "nan");
    let csv = std::fs::read_to_string(nan.join("runs.csv")).unwrap();
    let mut lines: Vec<String> = csv.lines().map(String::from).collect();
    let cells: Vec<&str> = lines[1].split(',').collect();
    let mut cells: Vec<String> = cells.iter().map(|c| c.to_string()).collect();
    // The row's first metric, after run, the two keys, seed and status.
    cells[5] = "NaN".into();
    lines[1] = cells.join(",");
    std::fs::write(nan.join("runs.csv"), lines.join("\n") + "\n").unwrap();
    refused(&[&nan, &shards[1]], "max_coordination_error = NaN, which no run writes");
    refused(&[&shards[0], &copy(&shards[0], "twice"), &shards[1]], "is done in both");
    let mixed = copy(&shards[0], "mixed");
    let theirs = std::fs::read_to_string(shards[1].join("runs.csv")).unwrap();
    let ours = std::fs::read_to_string(mixed.join("runs.csv")).unwrap();
    std::fs::write(mixed.join("runs.csv"), ours + theirs.split_once('\n').unwrap().1).unwrap();
    refused(&[&mixed, &shards[1]], "is not the runs of its shard 1/2");
    let edited = copy(&shards[1], "edited");
    let mission = std::fs::read_to_string(edited.join("mission.toml")).unwrap();
    std::fs::write(edited.join("mission.toml"), mission.replace("kc = 0.5", "kc = 5.0")).unwrap();
    refused(&[&shards[0], &edited], "not the mission this sweep ran");
    merge(&shards, &dir.join("merged"));
}

/// Stops a cluster that `tests/slurm/cluster` started, however the test ends.
struct Cluster(std::path::PathBuf);

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new(cluster_script()).arg("stop").arg(&self.0).status();
    }
}

fn cluster_script() -> String {
    format!("{}/tests/slurm/cluster", env!("CARGO_MANIFEST_DIR"))
}

/// The study as a Slurm job array on a one-node cluster of its own (munged, slurmctld and
/// slurmd on loopback), three array tasks each running its shard, then merged: the sweep's
/// tables, byte for byte.
#[test]
fn a_sweep_as_a_slurm_job_array_merges_into_the_sweep() {
    let dir = scratch("slurm");
    let whole = dir.join("whole");
    grid_sweep(&whole, &[]);
    let cluster = Cluster(dir.join("cluster"));
    let started = Command::new(cluster_script())
        .arg("start")
        .arg(&cluster.0)
        .output()
        .unwrap();
    let conf = String::from_utf8_lossy(&started.stdout).trim().to_string();
    assert!(
        started.status.success(),
        "{}{}",
        conf,
        String::from_utf8_lossy(&started.stderr)
    );
    // The job script of docs/EXPERIMENTS.md, with this build's tcpf.
    let job = dir.join("study.sbatch");
    std::fs::write(
        &job,
        format!(
            "#!/bin/sh\n#SBATCH --array=1-3\n#SBATCH --cpus-per-task=1\nexec \"$TCPF\" sweep {} {} --jobs 1 --shard \"$SLURM_ARRAY_TASK_ID/3\" --out \"shards/$SLURM_ARRAY_TASK_ID\"\n",
            config("paper/b-current"),
            GRID.join(" ")
        ),
    )
    .unwrap();
    let o = Command::new("sbatch")
        .args(["--wait", "--output=task-%a.out"])
        .arg("--chdir")
        .arg(&dir)
        .arg(&job)
        .env("SLURM_CONF", &conf)
        .env("TCPF", env!("CARGO_BIN_EXE_tcpf"))
        .output()
        .unwrap();
    let logs = || {
        (1..=3)
            .map(|i| std::fs::read_to_string(dir.join(format!("task-{i}.out"))).unwrap_or_default())
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert!(
        o.status.success(),
        "{}{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
        logs()
    );
    let shards: Vec<_> = (1..=3).map(|i| dir.join(format!("shards/{i}"))).collect();
    for s in &shards {
        assert!(s.join("runs.csv").is_file(), "{}: {}", s.display(), logs());
    }
    let merged = dir.join("merged");
    merge(&shards, &merged);
    assert!(tables(&merged) == tables(&whole), "the job array's shards merged");
}

/// The same study under GNU parallel, two shards at a time.
#[test]
fn a_sweep_under_gnu_parallel_merges_into_the_sweep() {
    let dir = scratch("parallel");
    let whole = dir.join("whole");
    grid_sweep(&whole, &[]);
    let o = Command::new("parallel")
        .args(["-j2", "--halt", "now,fail=1"])
        .arg(format!(
            "{} sweep {} {} --jobs 1 --shard {{}}/4 --out {}/shard-{{}}",
            env!("CARGO_BIN_EXE_tcpf"),
            config("paper/b-current"),
            GRID.join(" "),
            dir.display()
        ))
        .args([":::", "1", "2", "3", "4"])
        .output()
        .unwrap();
    ok(o);
    let shards: Vec<_> = (1..=4).map(|i| dir.join(format!("shard-{i}"))).collect();
    let merged = dir.join("merged");
    merge(&shards, &merged);
    assert!(tables(&merged) == tables(&whole));
}

/// After configs/outage.toml's 20 s outage the fleet is back within 0.1 s of γ (MODEL D16a) at
/// the time telemetry.csv shows, as summary.json, the sweep's runs.csv and the report say.
#[test]
fn the_resync_after_an_outage_is_what_the_telemetry_shows() {
    let dir = scratch("resync");
    let run = dir.join("run");
    ok(tcpf(&[
        "run",
        &config("outage"),
        "--in-process",
        "--out",
        run.to_str().unwrap(),
    ]));
    // γ of each vehicle per tick, from telemetry.csv.
    let rows = common::csv_rows(&run.join("telemetry.csv"));
    let mut gammas: std::collections::BTreeMap<u64, Vec<f64>> = Default::default();
    for r in &rows {
        gammas
            .entry(r["tick"].parse().unwrap())
            .or_default()
            .push(r["gamma"].parse().unwrap());
    }
    let dt = 0.01;
    let back = gammas
        .iter()
        .map(|(tick, g)| (*tick as f64 * dt, (g[0] - g[1]).abs()))
        .find(|(t, e)| *t >= 30.0 && *e <= 0.1)
        .map(|(t, _)| t - 30.0)
        .unwrap();
    let summary = json(&run.join("summary.json"));
    let fault = &summary["faults"][0];
    assert_eq!(
        (fault["kind"].as_str(), fault["start"].as_f64(), fault["end"].as_f64()),
        (Some("outage"), Some(10.0), Some(30.0))
    );
    let resync = fault["resync_time"].as_f64().unwrap();
    eprintln!("back in step {resync} s after the outage (telemetry: {back} s)");
    assert!((resync - back).abs() < 1e-9, "{resync} vs {back}");
    assert!((resync - 11.61).abs() < 0.005, "MODEL D16a prints 11.61 s: {resync}");
    // The error integral and rms are those of the telemetry's samples too.
    let first = summary["vehicles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["arrival_time"].as_f64().unwrap())
        .fold(f64::INFINITY, f64::min);
    let integral: f64 = gammas
        .iter()
        .filter(|(tick, _)| **tick > 0 && (**tick as f64) * dt <= first)
        .map(|(_, g)| (g[0] - g[1]).abs() * dt)
        .sum();
    let reported = summary["integral_coordination_error"].as_f64().unwrap();
    assert!((reported - integral).abs() < 0.05, "{reported} vs {integral}");
    // The report marks the window on its time plots and lists it.
    let html = std::fs::read_to_string(run.join("report.html")).unwrap();
    assert!(html.contains("<table id=\"fault-windows\">") && html.contains("<td>11.61</td>"));
    assert!(html.matches("fault window").count() >= 3, "on every time plot");
    // The sweep has it per run.
    let sweep = dir.join("sweep");
    ok(tcpf(&[
        "sweep",
        &config("outage"),
        "--loss",
        "0",
        "--seeds",
        "1",
        "--out",
        sweep.to_str().unwrap(),
    ]));
    let row = &common::csv_rows(&sweep.join("runs.csv"))[0];
    assert_eq!(row["resync_time"].parse::<f64>().unwrap(), resync);
    assert!(sweep.join("sweep-resync.svg").is_file());

    // configs/acoustic.toml: the lanes bow apart beyond the modems' 20 m; the window is the span
    // in which telemetry.csv has them farther apart than that.
    let acoustic = dir.join("acoustic");
    ok(tcpf(&[
        "run",
        &config("acoustic"),
        "--in-process",
        "--out",
        acoustic.to_str().unwrap(),
    ]));
    let mut at: std::collections::BTreeMap<u64, Vec<(f64, f64)>> = Default::default();
    for r in common::csv_rows(&acoustic.join("telemetry.csv")) {
        at.entry(r["tick"].parse().unwrap())
            .or_default()
            .push((r["x"].parse().unwrap(), r["y"].parse().unwrap()));
    }
    let beyond: Vec<f64> = at
        .iter()
        .filter(|(_, p)| (p[0].0 - p[1].0).hypot(p[0].1 - p[1].1) > 20.0)
        .map(|(tick, _)| *tick as f64 * dt)
        .collect();
    let summary = json(&acoustic.join("summary.json"));
    let window = &summary["faults"][0];
    assert_eq!(window["kind"], "out_of_range", "{summary}");
    assert_eq!(window["start"].as_f64(), beyond.first().copied());
    assert!((window["end"].as_f64().unwrap() - (beyond.last().unwrap() + dt)).abs() < 1e-9);
    eprintln!("out of range from {} s to {} s", window["start"], window["end"]);
}

/// `tcpf gen lanes` of four vehicles at loss 0.3, written into `dir`: a fleet whose topology
/// matters.
fn four_lanes(dir: &Path) -> std::path::PathBuf {
    let lanes = ok(tcpf(&["gen", "lanes", "--vehicles", "4", "--loss", "0.3"]));
    let mission = dir.join("lanes.toml");
    std::fs::write(&mission, &lanes.stdout).unwrap();
    mission
}

/// A categorical key (the topology of a fleet of four) draws a bar per value in every figure.
#[test]
fn a_categorical_sweep_draws_bars_per_metric() {
    let dir = scratch("topology");
    let mission = four_lanes(&dir);
    let out = dir.join("sweep");
    let o = ok(tcpf(&[
        "sweep",
        mission.to_str().unwrap(),
        "--param",
        "comms.topology=ring,complete,line",
        "--seeds",
        "3",
        "--out",
        out.to_str().unwrap(),
    ]));
    // The lanes keep their distance and arrive together whatever the graph, and broadcast 10
    // times a second: lines in the table, not flat figures.
    let said = String::from_utf8_lossy(&o.stdout);
    for (figure, line) in [
        ("sweep-clearance", "minimum clearance: 3.99 m in every run"),
        ("sweep-arrival", "last arrival: 75.3 s in every run"),
        ("sweep-messages", "γ broadcasts per vehicle: 10 1/s in every run"),
    ] {
        assert!(
            !out.join(format!("{figure}.svg")).exists() && said.contains(line),
            "{said}"
        );
    }
    for figure in ["sweep-error", "sweep-rms"] {
        let svg = std::fs::read_to_string(out.join(format!("{figure}.svg"))).unwrap();
        for topology in ["ring", "complete", "line"] {
            assert!(
                svg.contains(&format!("\n{topology}\n")),
                "{figure}: {topology} under its bar"
            );
        }
        assert!(svg.matches("<rect").count() >= 3, "{figure}: a bar per topology");
        assert!(out.join(format!("{figure}.pdf")).is_file());
    }
    let error = |t: &str| {
        common::csv_rows(&out.join("aggregate.csv"))
            .into_iter()
            .find(|a| a["comms.topology"] == t)
            .map(|a| a["max_coordination_error_mean"].parse::<f64>().unwrap())
            .unwrap()
    };
    assert!(
        error("line") > error("complete"),
        "a line of four coordinates worse than all pairs"
    );
}

/// The sweep's page renders in a real browser with every figure, and each figure is shot to
/// `target/tmp/screenshots/` for a reader to look at: the grid's (one curve per delay) and a
/// categorical sweep's (bars), and the report of a run with an outage (its fault window).
#[test]
fn the_sweeps_figures_render_in_a_real_browser() {
    let dir = scratch("sweep-browser");
    let shots = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("screenshots");
    std::fs::create_dir_all(&shots).unwrap();
    let grid = dir.join("grid");
    grid_sweep(&grid, &[]);
    let page = format!("file://{}", grid.join("sweep.html").display());
    let dom = String::from_utf8_lossy(&chromium(&["--dump-dom", &page]).stdout).to_string();
    for id in ["sweep-error", "sweep-rms", "sweep-clearance", "sweep-arrival"] {
        let start = dom
            .find(&format!("id=\"{id}\""))
            .unwrap_or_else(|| panic!("figure {id} missing from the rendered page"));
        let figure = &dom[start..start + dom[start..].find("</figure>").unwrap()];
        assert!(
            figure.matches("<polygon opacity=\"1\"").count() >= 6,
            "{id}: a marker per sampled loss"
        );
        assert!(figure.contains("<figcaption>"), "{id}: its caption beside it");
    }
    let topology = dir.join("topology");
    let mission = four_lanes(&dir);
    ok(tcpf(&[
        "sweep",
        mission.to_str().unwrap(),
        "--param",
        "comms.topology=ring,complete,line",
        "--loss",
        "0.1,0.5",
        "--seeds",
        "3",
        "--out",
        topology.to_str().unwrap(),
    ]));
    let outage = dir.join("outage");
    ok(tcpf(&[
        "run",
        &config("outage"),
        "--in-process",
        "--out",
        outage.to_str().unwrap(),
    ]));
    // A figure at its printed size (3.5 in: 336 CSS pixels), shot at twice that: what a reader
    // of the paper sees, magnified.
    for (source, name, size) in [
        (grid.join("sweep-error.svg"), "grid-error.png", "340,260"),
        (grid.join("sweep-clearance.svg"), "grid-clearance.png", "340,260"),
        (topology.join("sweep-error.svg"), "topology-error.png", "340,260"),
        (
            outage.join("figures/receptions.svg"),
            "outage-receptions.png",
            "340,260",
        ),
        (grid.join("sweep.html"), "grid-page.png", "1000,1600"),
        (outage.join("report.html"), "outage-report.png", "1000,2000"),
    ] {
        let shot = shots.join(name);
        let _ = std::fs::remove_file(&shot);
        let o = chromium(&[
            "--force-device-scale-factor=2",
            &format!("--window-size={size}"),
            &format!("--screenshot={}", shot.display()),
            &format!("file://{}", source.display()),
        ]);
        let bytes = std::fs::metadata(&shot).map(|m| m.len()).unwrap_or(0);
        assert!(
            bytes > 10_000,
            "{name}: a screenshot with something on it ({bytes} bytes): {}",
            String::from_utf8_lossy(&o.stderr)
        );
        eprintln!("screenshot: {}", shot.display());
    }
}

/// The words of an SVG figure: each `<text>`'s content (plotters writes it on its own line).
fn texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|t| Some(t.split_once('>')?.1.split("</text>").next()?.trim().to_string()))
        .collect()
}

/// The outlines of an SVG's filled polygons, by their number of corners: the markers.
fn corners(svg: &str) -> std::collections::BTreeSet<usize> {
    svg.split("<polygon ")
        .skip(1)
        .filter_map(|p| {
            let tag = p.split('>').next()?;
            Some(
                tag.split_once(" points=\"")?
                    .1
                    .split('"')
                    .next()?
                    .split_whitespace()
                    .count(),
            )
        })
        .collect()
}

/// Every figure of a sweep and of a run's report prints at a column's 3.5 in with no text under
/// 8 pt, says words and units instead of mission keys, has no title inside (its caption is
/// beside it), tells its families apart by marker as well as colour, and a metric the same at
/// every grid point gets a line, not a figure. `--figure-width double` draws them at 7.16 in.
#[test]
fn figures_print_at_eight_points_with_words_and_units_and_families_told_apart() {
    use tcpf_report::style::printed_text_sizes;
    let dir = scratch("print");
    let out = dir.join("grid");
    let o = grid_sweep(&out, &[]);
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(
        table.contains("γ broadcasts per vehicle: 10 1/s in every run, to three significant digits (no figure)"),
        "{table}"
    );
    assert!(!out.join("sweep-messages.svg").exists(), "no figure of a constant");
    let html = std::fs::read_to_string(out.join("sweep.html")).unwrap();
    for figure in ["sweep-error", "sweep-rms", "sweep-clearance", "sweep-arrival"] {
        let svg = std::fs::read_to_string(out.join(format!("{figure}.svg"))).unwrap();
        assert!(svg.contains("width=\"3.500in\""), "{figure}: a column wide");
        let sizes = printed_text_sizes(&svg);
        assert!(sizes.len() >= 10, "{figure}: {sizes:?}");
        let small = sizes.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(small >= 8.0, "{figure}: a text of {small:.2} pt");
        let words = texts(&svg);
        for key in ["comms.loss", "comms.delay"] {
            assert!(
                !words.iter().any(|w| w.contains(key)),
                "{figure}: {key} written as a key: {words:?}"
            );
        }
        assert!(words.iter().any(|w| w == "message loss probability"), "{words:?}");
        assert!(
            words.iter().any(|w| w == "delay 0 s") && words.iter().any(|w| w == "delay 1 s"),
            "legends with units: {words:?}"
        );
        assert!(!words.iter().any(|w| w == "Coordination error"), "no title inside");
        // Circles (16 corners) for one family, squares (4) for the other; the first a solid
        // line (one polyline for the data, one in the legend), the second dashed (a polyline a
        // dash).
        let shapes = corners(&svg);
        assert!(shapes.contains(&16) && shapes.contains(&4), "{figure}: {shapes:?}");
        let strokes = |colour: &str| {
            svg.split("<polyline")
                .filter(|p| {
                    p.split('>')
                        .next()
                        .unwrap_or("")
                        .contains(&format!("stroke=\"{colour}\""))
                })
                .count()
        };
        assert_eq!(strokes("#0072B2"), 2, "{figure}: delay 0 s solid");
        assert!(strokes("#D55E00") > 10, "{figure}: delay 1 s dashed");
        let pdf = String::from_utf8_lossy(&std::fs::read(out.join(format!("{figure}.pdf"))).unwrap()).to_string();
        assert!(pdf.contains("/MediaBox [0 0 252 "), "{figure}: 3.5 in of PDF");
        let caption = std::fs::read_to_string(out.join(format!("{figure}.txt"))).unwrap();
        assert!(caption.contains("95 % confidence interval"), "{caption}");
        assert!(html.contains(&format!("<figcaption>{}</figcaption>", caption.trim())));
    }
    let error = texts(&std::fs::read_to_string(out.join("sweep-error.svg")).unwrap());
    assert!(error.iter().any(|w| w == "coordination error (s)"), "{error:?}");

    let double = dir.join("double");
    grid_sweep(&double, &["--figure-width", "double"]);
    let svg = std::fs::read_to_string(double.join("sweep-error.svg")).unwrap();
    assert!(svg.contains("width=\"7.160in\""));
    assert!(printed_text_sizes(&svg).iter().all(|s| *s >= 8.0));

    let run = dir.join("outage");
    ok(tcpf(&[
        "run",
        &config("outage"),
        "--in-process",
        "--out",
        run.to_str().unwrap(),
    ]));
    // A run that drops nothing has bars of nothing: drawn as no shape, not one the PDF's
    // reader warns of in the user's terminal.
    let quiet = ok(tcpf(&[
        "run",
        &config("paper/b-current"),
        "--in-process",
        "--out",
        dir.join("quiet").to_str().unwrap(),
    ]));
    let said = String::from_utf8_lossy(&quiet.stderr);
    assert!(!said.contains("WARN"), "{said}");
    let mut figures = 0;
    for entry in std::fs::read_dir(run.join("figures")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "svg") {
            let svg = std::fs::read_to_string(&path).unwrap();
            let small = printed_text_sizes(&svg).into_iter().fold(f64::INFINITY, f64::min);
            assert!(small >= 8.0, "{}: a text of {small:.2} pt", path.display());
            assert!(path.with_extension("pdf").is_file() && path.with_extension("txt").is_file());
            let lower = svg.to_lowercase();
            assert!(
                !lower.contains("#e6194b") && !lower.contains("#3cb44b"),
                "{}: red and green",
                path.display()
            );
            figures += 1;
        }
    }
    assert!(figures >= 8, "every figure of the report: {figures}");
    ok(tcpf(&["report", run.to_str().unwrap(), "--figure-width", "double"]));
    let paths = std::fs::read_to_string(run.join("figures/paths.svg")).unwrap();
    assert!(paths.contains("width=\"7.160in\""), "redrawn two columns wide");
    let o = tcpf(&["report", run.to_str().unwrap(), "--figure-width", "1"]);
    assert_eq!(o.status.code(), Some(2), "a width no page has is bad input");
}

/// A sweep of fleets interrupted by Ctrl-C after some runs, then `--resume`d, writes the tables
/// the sweep writes uninterrupted (here in-process: the same runs give the same rows); the run
/// cut short is set aside, not in the way, and no kept run directory holds a password.
#[test]
fn an_interrupted_sweep_of_fleets_resumes_to_the_tables_of_one_never_interrupted() {
    let _fleet = fleet();
    let dir = scratch("resume-processes");
    let (out, whole) = (dir.join("cut"), dir.join("whole"));
    let mission = config("paper/b-current");
    let grid = ["--loss", "0,0.5", "--seeds", "2"];
    let mut sweep = Reaper(
        Command::new(env!("CARGO_BIN_EXE_tcpf"))
            .args(["sweep", &mission])
            .args(grid)
            .args(["--processes", "--out", out.to_str().unwrap()])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap(),
    );
    let rows = || std::fs::read_to_string(out.join("runs.csv")).map_or(0, |s| s.lines().count().saturating_sub(1));
    let started = std::time::Instant::now();
    while rows() < 2 {
        assert!(started.elapsed().as_secs() < 120, "two runs done");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    // Into the third run: its fleet is under way.
    std::thread::sleep(std::time::Duration::from_millis(300));
    kill("-INT", sweep.0.id());
    let status = sweep.0.wait().unwrap();
    assert_eq!(status.code(), Some(130), "an interrupted sweep exits 130");
    let mut said = String::new();
    std::io::Read::read_to_string(sweep.0.stdout.as_mut().unwrap(), &mut said).unwrap();
    assert!(said.contains("--resume runs the rest"), "{said}");
    let resumed = ok(tcpf(&[
        "sweep",
        &mission,
        grid[0],
        grid[1],
        grid[2],
        grid[3],
        "--processes",
        "--resume",
        "--out",
        out.to_str().unwrap(),
    ]));
    let summary = json(&out.join("sweep.json"));
    assert_eq!(
        summary["interrupted"],
        false,
        "{}",
        String::from_utf8_lossy(&resumed.stdout)
    );
    assert_eq!(summary["done_runs"], 4);
    ok(tcpf(&[
        "sweep",
        &mission,
        grid[0],
        grid[1],
        grid[2],
        grid[3],
        "--out",
        whole.to_str().unwrap(),
    ]));
    assert_eq!(tables(&out), tables(&whole), "runs.csv and aggregate.csv byte for byte");
    let runs: Vec<std::path::PathBuf> = std::fs::read_dir(out.join("runs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    let kept: Vec<&std::path::PathBuf> = runs
        .iter()
        .filter(|p| !p.to_string_lossy().contains(".attempt-"))
        .collect();
    assert_eq!(kept.len(), 4, "{runs:?}");
    for run in &runs {
        for secret in [
            "credentials",
            "zenoh.json5",
            "world.json5",
            "agent-1.json5",
            "observer.json5",
        ] {
            assert!(!run.join(secret).exists(), "{}: {secret} kept", run.display());
        }
    }
    for run in kept {
        assert!(run.join("rerun.sh").is_file() && run.join("telemetry.csv").is_file());
    }
}

/// `--series` keeps, per grid point, e(t) and d(t) over the seeds: at every sample, the mean of
/// what each run's own telemetry says at that tick. rerun.sh draws it again, as it was drawn.
#[test]
fn a_series_is_the_mean_of_the_runs_telemetry_at_each_tick() {
    let dir = scratch("series");
    let mission = config("paper/b-current");
    let out = dir.join("sweep");
    ok(tcpf(&[
        "sweep",
        &mission,
        "--loss",
        "0.3",
        "--seeds",
        "3",
        "--series",
        "--band",
        "min-max",
        "--figure-width",
        "double",
        "--out",
        out.to_str().unwrap(),
    ]));
    let series = common::csv_rows(&out.join("series.csv"));
    assert!(
        series.len() > 500,
        "a sample every 0.1 s of a 55 s run: {}",
        series.len()
    );
    // Each run's e and d at each tick, from its telemetry.
    let mut runs = Vec::new();
    for seed in 1..=3 {
        let run = dir.join(format!("run{seed}"));
        ok(tcpf(&[
            "run",
            &mission,
            "--set",
            "comms.loss=0.3",
            "--seed",
            &seed.to_string(),
            "--in-process",
            "--out",
            run.to_str().unwrap(),
        ]));
        let mut ticks: std::collections::BTreeMap<u64, Vec<(f64, f64, f64)>> = Default::default();
        for row in common::csv_rows(&run.join("telemetry.csv")) {
            let f = |k: &str| row[k].parse::<f64>().unwrap();
            ticks
                .entry(row["tick"].parse().unwrap())
                .or_default()
                .push((f("gamma"), f("x"), f("y")));
        }
        runs.push(ticks);
    }
    let at = |tick: u64| {
        let (mut e, mut d) = (Vec::new(), Vec::new());
        for ticks in &runs {
            let Some(rows) = ticks.get(&tick) else { continue };
            let g = rows.iter().map(|r| r.0);
            e.push(g.clone().fold(f64::NEG_INFINITY, f64::max) - g.fold(f64::INFINITY, f64::min));
            let mut near = f64::INFINITY;
            for (i, a) in rows.iter().enumerate() {
                for b in &rows[i + 1..] {
                    near = near.min((a.1 - b.1).hypot(a.2 - b.2));
                }
            }
            d.push(near);
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        (e.len(), mean(&e), mean(&d))
    };
    let mut checked = 0;
    for row in series.iter().step_by(37) {
        let t: f64 = row["t"].parse().unwrap();
        let tick = (t / 0.01).round() as u64;
        let (n, e, d) = at(tick);
        assert_eq!(row["n"], n.to_string(), "t = {t}");
        let (se, sd): (f64, f64) = (
            row["error_mean"].parse().unwrap(),
            row["clearance_mean"].parse().unwrap(),
        );
        assert!(
            (se - e).abs() < 1e-9 && (sd - d).abs() < 1e-9,
            "t = {t}: {se} vs {e}, {sd} vs {d}"
        );
        checked += 1;
    }
    assert!(checked > 10);
    for figure in ["series-error", "series-clearance"] {
        assert!(out.join(format!("{figure}.svg")).is_file() && out.join(format!("{figure}.pdf")).is_file());
    }
    let again = dir.join("again");
    ok(Command::new(out.join("rerun.sh"))
        .arg(&again)
        .env("TCPF", env!("CARGO_BIN_EXE_tcpf"))
        .output()
        .unwrap());
    for file in ["series.csv", "series-error.svg", "sweep-error.svg"] {
        assert!(
            std::fs::read(again.join(file)).unwrap() == std::fs::read(out.join(file)).unwrap(),
            "{file} drawn again by rerun.sh is not the first: {}",
            std::fs::read_to_string(out.join("rerun.sh")).unwrap()
        );
    }
    let svg = std::fs::read_to_string(out.join("series-error.svg")).unwrap();
    assert!(svg.starts_with("<svg width=\"7.160in\""), "{}", &svg[..80]);
}
