//! Helpers the tests of the `tcpf` binary share.
// Each test crate uses its own subset of these.
#![allow(dead_code)]

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

mod held;
pub mod testbed;
pub use held::held_gamma_s;

pub fn tcpf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args(args)
        .output()
        .expect("tcpf runs")
}

/// The tests' fleet credential, made once per test process by `tcpf credential`: a role started
/// by hand demands one (or `--open`).
pub fn credential() -> &'static Path {
    static FILE: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    FILE.get_or_init(|| {
        let file = scratch("credential").join("fleet.key");
        let o = tcpf(&["credential", file.to_str().unwrap()]);
        assert!(o.status.success(), "{}", text(&o));
        file
    })
}

/// The arguments of a role started by hand, with `--credential` of the tests' credential unless
/// they give a Zenoh config of their own (`-c`) or run open.
pub fn credentialed(args: &[&str]) -> Vec<String> {
    let mut all: Vec<String> = args.iter().map(|a| a.to_string()).collect();
    if !args
        .iter()
        .any(|a| matches!(*a, "-c" | "--config" | "--open" | "--credential"))
    {
        all.extend(["--credential".into(), credential().display().to_string()]);
    }
    all
}

/// `tcpf record` of `mission` into `out`, joining the fleet started by hand at `endpoint` with the
/// tests' credential.
pub fn record_by_hand(mission: &str, endpoint: &str, out: &Path) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_tcpf"));
    command.args(credentialed(&[
        "record",
        mission,
        "-e",
        endpoint,
        "--out",
        out.to_str().unwrap(),
    ]));
    command
}

/// The tests' credential as Zenoh's `transport/auth/usrpwd` of a session opened by a test.
pub fn usrpwd() -> String {
    let text = std::fs::read_to_string(credential()).unwrap();
    let (user, password) = text.trim().split_once(':').unwrap();
    serde_json::json!({ "user": user, "password": password }).to_string()
}

/// `tcpf gen lanes --vehicles n`, written into `dir`: a fleet of any size.
pub fn lanes(dir: &Path, n: u32) -> PathBuf {
    let o = tcpf(&["gen", "lanes", "--vehicles", &n.to_string()]);
    assert!(o.status.success(), "{}", text(&o));
    let file = dir.join(format!("lanes{n}.toml"));
    std::fs::write(&file, &o.stdout).unwrap();
    file
}

/// The right to start a fleet, held until dropped: two cores run one fleet's processes, and two
/// fleets side by side starve each other (realtime agents miss their periods, lockstep worlds
/// wait past their timeouts), so a test that starts one takes this first, before its children,
/// so that they are gone before the next fleet starts. A lock on a file, not in memory: it
/// holds across test binaries and `cargo test` invocations run at once.
pub struct FleetSlot(#[allow(dead_code)] std::fs::File);

pub fn fleet() -> FleetSlot {
    let file = std::fs::File::create(std::env::temp_dir().join("tcpf-tests-fleet.lock")).expect("the fleet lock file");
    file.lock().expect("the fleet lock");
    // The test drives the fleet (kills a role at t = 5 s, cuts a link at 10 s) and times it
    // from what the fleet writes: it must run when the fleet does, not behind whatever else the
    // machine runs that a realtime fleet overtakes (bus/src/priority.rs).
    tcpf_bus::priority::for_realtime("the test");
    FleetSlot(file)
}

/// `configs/<name>.toml`.
pub fn config(name: &str) -> String {
    format!("{}/configs/{name}.toml", env!("CARGO_MANIFEST_DIR"))
}

pub fn paper(case: &str) -> String {
    config(&format!("paper/{case}"))
}

/// A fresh directory of this test process.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "tcpf-{}-{}-{name}",
        env!("CARGO_CRATE_NAME"),
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Everything a command printed.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// (pid, parent pid, state) of every process.
pub fn processes() -> Vec<(u32, u32, char)> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(entry.path().join("stat")) else {
            continue;
        };
        // The command name is in parentheses and may hold spaces: parse after the last ')'.
        let rest: Vec<&str> = stat[stat.rfind(')').unwrap() + 2..].split(' ').collect();
        out.push((pid, rest[1].parse().unwrap(), rest[0].chars().next().unwrap()));
    }
    out
}

pub fn descendants(root: u32) -> Vec<u32> {
    let all = processes();
    let mut found = vec![root];
    let mut k = 0;
    while k < found.len() {
        let parent = found[k];
        found.extend(all.iter().filter(|p| p.1 == parent).map(|p| p.0));
        k += 1;
    }
    found.remove(0);
    found
}

/// The pid of the agent of vehicle `id` under `root`, if one runs there.
pub fn agent_under(root: u32, id: u32) -> Option<u32> {
    let id = id.to_string();
    find_pid(root, |args| {
        args.contains(&&b"agent"[..]) && args.windows(2).any(|w| w[0] == b"--id" && w[1] == id.as_bytes())
    })
}

pub fn alive(pid: u32) -> bool {
    processes().iter().any(|p| p.0 == pid && p.2 != 'Z')
}

pub fn kill(signal: &str, pid: u32) {
    let _ = Command::new("kill").args([signal, &pid.to_string()]).status();
}

/// Sends SIGKILL to `pid` and waits, at most `within`, until it has exited (gone, or a zombie
/// its parent has yet to reap); how long that took. A killed process closes its connections
/// only as it exits, and the fleet sees it leave only then: beside a CPU hog the kernel kept a
/// killed agent in D state (`unlink_file_vma_batch_process`, the lock of the binary's mapping,
/// which every tcpf process shares) for 1.1 s of 20 kills, and a test that failed because the
/// world saw its agent leave late says so by this figure.
pub fn kill_and_wait(pid: u32, within: Duration) -> Duration {
    let killed = Instant::now();
    kill("-9", pid);
    while alive(pid) && killed.elapsed() < within {
        std::thread::sleep(Duration::from_millis(5));
    }
    killed.elapsed()
}

/// A child that is killed, with everything under it, when dropped: a failing test leaves no
/// process behind.
pub struct Reaper(pub std::process::Child);

impl Drop for Reaper {
    fn drop(&mut self) {
        for pid in descendants(self.0.id()) {
            kill("-9", pid);
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A `tcpf run` that is killed with everything under it when dropped.
pub struct Launch {
    pub child: Child,
    pub out: PathBuf,
}

impl Launch {
    pub fn start(mission: &str, out: &Path, extra: &[&str]) -> Launch {
        Launch::spawn(Command::new(env!("CARGO_BIN_EXE_tcpf")), mission, out, extra)
    }

    /// `tcpf run` in a process group of its own, as a shell starts a job: `kill(-pid)` is then
    /// what the terminal's Ctrl-C sends, to the whole group.
    pub fn start_as_a_job(mission: &str, out: &Path, extra: &[&str]) -> Launch {
        use std::os::unix::process::CommandExt;
        let mut command = Command::new(env!("CARGO_BIN_EXE_tcpf"));
        command.process_group(0);
        Launch::spawn(command, mission, out, extra)
    }

    /// `tcpf run` started by `command` (the binary itself, or a tool that runs it).
    pub fn spawn(mut command: Command, mission: &str, out: &Path, extra: &[&str]) -> Launch {
        let child = command
            .args(["run", mission, "--out", out.to_str().unwrap()])
            .args(extra)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        Launch {
            child,
            out: out.to_path_buf(),
        }
    }

    pub fn wait(&mut self, limit: Duration) -> ExitStatus {
        let deadline = Instant::now() + limit;
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status;
            }
            assert!(Instant::now() < deadline, "tcpf run did not finish within {limit:?}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Waits until `file` in the run directory contains `text`.
    pub fn wait_for(&self, file: &str, text: &str) {
        wait_for_text(&self.out.join(file), text, Duration::from_secs(60));
    }

    pub fn summary(&self) -> Value {
        serde_json::from_str(&std::fs::read_to_string(self.out.join("summary.json")).unwrap()).unwrap()
    }
}

impl Drop for Launch {
    fn drop(&mut self) {
        for pid in descendants(self.child.id()) {
            kill("-9", pid);
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub fn run_in_process(mission: &str, out: &Path, extra: &[&str]) {
    let status = Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args(["run", mission, "--in-process", "--out", out.to_str().unwrap()])
        .args(extra)
        .stdout(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
}

pub fn summary(dir: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

/// The child of `role` in a summary (the first, for agents).
pub fn child_of<'a>(summary: &'a Value, role: &str) -> &'a Value {
    summary["children"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["role"] == role)
        .unwrap_or_else(|| panic!("no {role} among the children: {summary}"))
}

/// A summary's `failure`, which must be there.
pub fn failure(summary: &Value) -> &str {
    summary["failure"]
        .as_str()
        .unwrap_or_else(|| panic!("no failure in the summary: {summary}"))
}

pub const METRICS: [&str; 6] = [
    "t_f",
    "ticks",
    "max_coordination_error",
    "min_clearance",
    "max_coordination_error_to_last_arrival",
    "min_clearance_to_last_arrival",
];

pub fn assert_same_run(processes: &Path, in_process: &Path) {
    for file in ["telemetry.csv", "messages.csv"] {
        let a = std::fs::read(processes.join(file)).unwrap();
        let b = std::fs::read(in_process.join(file)).unwrap();
        assert!(a == b, "{file} differs between processes and in-process");
    }
    let (sa, sb) = (summary(processes), summary(in_process));
    for key in METRICS {
        assert_eq!(sa[key], sb[key], "{key}");
    }
    assert_eq!(sa["vehicles"], sb["vehicles"]);
    assert_eq!(sa["links"], sb["links"]);
    assert_eq!(sa["mode"], "processes");
    assert_eq!(sb["mode"], "in-process");
}

/// The pid of the process under `root` whose arguments `matches`, if one runs there.
pub fn find_pid(root: u32, matches: impl Fn(&[&[u8]]) -> bool) -> Option<u32> {
    descendants(root).into_iter().find(|pid| {
        let cmdline = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
        matches(&cmdline.split(|b| *b == 0).collect::<Vec<_>>())
    })
}

/// The pid of the process under `root` whose arguments `matches` (`what` it is, for the panic).
pub fn pid_of(root: u32, what: &str, matches: impl Fn(&[&[u8]]) -> bool) -> u32 {
    find_pid(root, matches).unwrap_or_else(|| panic!("{what} runs"))
}

/// Stops the planner of a launch with SIGTERM.
pub fn stop_the_planner(launch: &Launch) {
    let planner = pid_of(launch.child.id(), "the planner", |args| {
        args.get(1) == Some(&&b"planner"[..])
    });
    kill("-TERM", planner);
}

/// A launch whose planner was stopped once its fleet ran: it completes, and its summary warns
/// that the planner exited. Returns the summary.
pub fn went_on_without_its_planner(launch: &mut Launch, limit: Duration) -> Value {
    let status = launch.wait(limit);
    let s = launch.summary();
    assert!(status.success(), "{s}");
    assert_eq!(s["completed"], true, "{s}");
    let warning = s["warnings"][0].as_str().unwrap_or_default();
    assert!(
        warning.starts_with("the planner exited (code 130) after serving the paths"),
        "{s}"
    );
    s
}

/// Every vehicle's arrival time in a summary, in order; a vehicle that did not arrive fails.
pub fn arrivals(s: &Value) -> Vec<f64> {
    s["vehicles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| {
            v["arrival_time"]
                .as_f64()
                .unwrap_or_else(|| panic!("vehicle {} did not arrive", v["id"]))
        })
        .collect()
}

pub fn assert_none_left(summary: &Value) {
    for c in summary["children"].as_array().unwrap() {
        let pid = c["pid"].as_u64().unwrap() as u32;
        assert!(!alive(pid), "{} {} (pid {pid}) still running", c["role"], c["id"]);
    }
}

/// The tick and time (s) of a whole row near the end of `out`'s telemetry.csv (the last line
/// may be half written), if it has one.
pub fn last_recorded(out: &Path) -> Option<(u64, f64)> {
    let text = std::fs::read_to_string(out.join("telemetry.csv")).ok()?;
    let mut fields = text.lines().rev().nth(1)?.split(',');
    Some((fields.next()?.parse().ok()?, fields.next()?.parse().ok()?))
}

/// Waits until the telemetry in run directory `out` reaches simulated time `t`.
pub fn wait_until_simulated(out: &Path, t: f64) {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        if last_recorded(out).is_some_and(|(_, now)| now >= t) {
            return;
        }
        assert!(Instant::now() < deadline, "the run never reached t = {t} s");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The timing entry of `role` `id` in a realtime summary.
pub fn timing<'a>(s: &'a Value, role: &str, id: u64) -> &'a Value {
    s["timing"]
        .as_array()
        .expect("a realtime summary has timing")
        .iter()
        .find(|t| t["role"] == role && t["id"] == id)
        .unwrap_or_else(|| panic!("no timing of {role} {id}: {}", s["timing"]))
}

/// The periods the realtime world integrated vehicle `id` without a command.
pub fn without_command(s: &Value, id: u64) -> u64 {
    timing(s, "world", 0)["without_command"]
        .as_array()
        .unwrap()
        .iter()
        .find(|v| v[0] == id)
        .and_then(|v| v[1].as_u64())
        .unwrap_or(0)
}

/// The γ of a realtime run that a receiver knew at another age than the run's usual one (its
/// receiver late past the instant, or the γ late to it), or never judged because a newer one
/// overtook it: each makes one vehicle know its neighbour a comms period better or worse than
/// the other does. `out` is the run directory of summary `s`, control period `period` s.
pub fn uneven_gamma(s: &Value, out: &Path, period: f64) -> u64 {
    let overtaken: u64 = s["links"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["overtaken"].as_u64().unwrap())
        .sum();
    let ages: Vec<i64> = csv_rows(&out.join("messages.csv"))
        .iter()
        .map(|r| {
            let age = r["t"].parse::<f64>().unwrap() - r["sent_t"].parse::<f64>().unwrap();
            (age / period).round() as i64
        })
        .collect();
    let usual = ages
        .iter()
        .max_by_key(|a| ages.iter().filter(|b| b == a).count())
        .copied()
        .unwrap_or(0);
    ages.iter().filter(|&&a| a != usual).count() as u64 + overtaken
}

/// How far a realtime run of a 10 ms period may be from lockstep, from the timing it reports.
pub struct Allowed {
    /// Periods disturbed: a command held over, a period skipped, an agent acting on an older state.
    pub disturbed: u64,
    /// γ a receiver knew at another age than the run's usual one, or never judged (overtaken).
    pub uneven: u64,
    /// s, of each arrival.
    pub arrival: f64,
    /// s, of the maximum coordination error.
    pub error: f64,
}

/// An arrival is seen on a tick, and the realtime world may see it a tick later (two periods,
/// with the start); then each disturbed period shifts a vehicle by a small part of a period's
/// travel, counted here as a tenth of a period each. Measured at x10 on 2 cores, case (b): 14
/// runs (6 beside a CPU hog), 27 to 161 disturbed periods, arrivals within 0.017 s of lockstep's,
/// errors within 0.009 s; MEDUSA case (b): 9 runs (4 beside a hog), 29 to 138 disturbed, arrivals
/// within 0.009 s, errors 0.007 s.
///
/// Coordination adds its own: in realtime an instant's γ is judged at the receiver's next one, a
/// comms period T_c old, by both vehicles alike. A γ judged at another age (its receiver late
/// past the instant, so the γ came first), or overtaken before an instant, means one vehicle knew
/// its neighbour T_c better or worse than the other did, for T_c: eq. 25's correction is off by
/// at most k_c T_c (γ̇ ≈ 1) for T_c, k_c T_c² of arrival each. A quiet run has a handful (3
/// MEDUSA runs at x10: 7 to 24); beside a CPU hog an agent starved past its instants makes
/// hundreds, which the dead zones of MEDUSA's thrusters turn into a real delay (one run: 441, 155 of them
/// overtaken, arrivals 0.43 s after lockstep's). The error also holds what an agent starved past
/// whole periods left the world holding (`held_gamma_s`).
pub fn allowed(realtime: &Value, out: &Path) -> Allowed {
    let period = 0.01;
    let disturbed: u64 = realtime["timing"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            ["late_commands", "skipped", "stale_states"]
                .iter()
                .map(|k| t[k].as_u64().unwrap())
                .sum::<u64>()
        })
        .sum();
    let mission: toml::Table = std::fs::read_to_string(out.join("mission.toml"))
        .unwrap()
        .parse()
        .unwrap();
    let comms_period = mission["comms"]["period"].as_float().unwrap();
    let uneven = uneven_gamma(realtime, out, period);
    let kc = realtime["coordination_gain"]["effective"].as_f64().unwrap();
    let coordination = uneven as f64 * kc * comms_period * comms_period;
    let slack = disturbed as f64 / 10.0;
    Allowed {
        disturbed,
        uneven,
        arrival: period * (2.0 + slack) + coordination,
        error: period * (1.0 + slack) + coordination + held_gamma_s(realtime),
    }
}

/// A loopback endpoint on a port free a moment ago.
pub fn free_endpoint() -> String {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    format!("tcp/127.0.0.1:{port}")
}

/// The process `start` makes on a loopback endpoint, once it listens there, and that endpoint.
/// A port free a moment ago may be taken (by another test's process) before the one started
/// binds it: then it starts again on another port, until it holds the listening socket itself.
/// `endpoint` (`tcp/HOST:PORT`) over TLS: where a fleet of certificates meets.
pub fn over_tls(endpoint: &str) -> String {
    endpoint.replacen("tcp/", "tls/", 1)
}

pub fn listening(start: impl Fn(&str) -> Child) -> (Child, String) {
    let mut exits = Vec::new();
    for _ in 0..5 {
        let endpoint = free_endpoint();
        let port: u16 = endpoint.rsplit(':').next().unwrap().parse().unwrap();
        let mut child = start(&endpoint);
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            if let Some(status) = child.try_wait().unwrap() {
                exits.push(format!("{endpoint}: {status}"));
                break;
            }
            if holds_listener(child.id(), port) {
                return (child, endpoint);
            }
            if Instant::now() > deadline {
                let _ = child.kill();
                panic!("nothing listens at {endpoint} after 30 s");
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
    panic!("the process to listen exited each time: {exits:?}")
}

/// Waits until the file at `path` (a role's log) says `text`, at most `limit`.
pub fn wait_for_text(path: &Path, text: &str, limit: Duration) {
    let deadline = Instant::now() + limit;
    while !std::fs::read_to_string(path).is_ok_and(|s| s.contains(text)) {
        assert!(Instant::now() < deadline, "{} never said {text:?}", path.display());
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Whether process `pid` holds a socket listening on loopback TCP `port`.
fn holds_listener(pid: u32, port: u16) -> bool {
    let tcp = std::fs::read_to_string("/proc/net/tcp").unwrap_or_default();
    // Columns: sl, local address (hex ip:port), remote, state (0A: listen), ..., inode (tenth).
    let sockets: Vec<String> = tcp
        .lines()
        .skip(1)
        .filter_map(|line| {
            let f: Vec<&str> = line.split_whitespace().collect();
            let local = u16::from_str_radix(f.get(1)?.rsplit(':').next()?, 16).ok()?;
            let inode = f.get(9)?;
            (local == port && f.get(3) == Some(&"0A")).then(|| format!("socket:[{inode}]"))
        })
        .collect();
    let fds = std::fs::read_dir(format!("/proc/{pid}/fd"))
        .into_iter()
        .flatten()
        .flatten();
    fds.filter_map(|fd| std::fs::read_link(fd.path()).ok())
        .any(|link| sockets.iter().any(|s| link.as_os_str() == s.as_str()))
}

/// Waits for `child` to exit (at most `limit`, or says `what` is still running) and returns its
/// exit code and standard error.
pub fn exited(child: &mut Child, limit: Duration, what: &str) -> (Option<i32>, String) {
    let code = wait_exit(child, limit, what);
    let mut stderr = String::new();
    child.stderr.take().unwrap().read_to_string(&mut stderr).unwrap();
    (code, stderr)
}

/// The exit code of `child` once it has exited, within `limit`: else it is killed, and the test
/// fails with `what` and what the child said, where its standard error is piped.
pub fn wait_exit(child: &mut Child, limit: Duration, what: &str) -> Option<i32> {
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status.code();
        }
        if started.elapsed() >= limit {
            // What it said, for the failure to show why it is still running.
            let _ = child.kill();
            let _ = child.wait();
            let mut stderr = String::new();
            if let Some(mut e) = child.stderr.take() {
                let _ = e.read_to_string(&mut stderr);
            }
            panic!("{what}: still running after {limit:?}; it said:\n{stderr}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

// The build's own rule for the commit it records (build.rs includes it too).
include!("../../build/commit.rs");

/// Checks a provenance (summary.json's or sweep.json's) against the arguments `tcpf` was given
/// and the mission it ran (`mission_toml`, its text as run): the command, the version, the
/// commit where built from a checkout, the digest. The command line, joined, for the caller.
pub fn assert_provenance(p: &Value, args: &[&str], mission_toml: &str) -> String {
    let command: Vec<&str> = p["command"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    assert_eq!(command[1..], *args, "{p}");
    assert_eq!(p["version"], env!("CARGO_PKG_VERSION"));
    match commit_of(Path::new(env!("CARGO_MANIFEST_DIR"))) {
        Some(head) => assert_eq!(p["commit"], head.as_str(), "built from this checkout's HEAD"),
        None => assert!(p.get("commit").is_none(), "{p}"),
    }
    let digest = format!("{:016x}", tcpf_core::mission::digest_of(mission_toml));
    assert_eq!(p["mission_digest"], digest.as_str());
    command.join(" ")
}

/// The rows of a CSV file with a header (`runs.csv`, `aggregate.csv`), each by column name.
pub fn csv_rows(file: &Path) -> Vec<std::collections::BTreeMap<String, String>> {
    let mut reader = csv::Reader::from_path(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    reader
        .records()
        .map(|r| {
            header
                .iter()
                .cloned()
                .zip(r.unwrap().iter().map(String::from))
                .collect()
        })
        .collect()
}

/// A child logging into `logs/NAME.log`.
pub fn logged(logs: &Path, name: &str, program: &str, args: &[&str]) -> Child {
    let log = std::fs::File::create(logs.join(format!("{name}.log"))).unwrap();
    Command::new(program)
        .args(args)
        .stdout(Stdio::from(log.try_clone().unwrap()))
        .stderr(Stdio::from(log))
        .spawn()
        .unwrap()
}

/// Case (b) by hand, its world simulating vehicle 1 alone (`--vehicles 1`): the planner, the
/// world and both agents, `settings` given to each, logging into `logs`. Returns them and the
/// endpoint; playing vehicle 2, and recording, is the caller's. With the tests' shared
/// credential the planner listens; with `keys`, a fleet directory of `tcpf credential DIR
/// MISSION`, a router given it does, over TLS, and each role presents its own certificate.
pub fn fleet_without_vehicle_2(
    mission: &str,
    logs: &Path,
    settings: &[&str],
    keys: Option<&Path>,
) -> (Vec<Reaper>, String) {
    std::fs::create_dir_all(logs).unwrap();
    let tcpf = env!("CARGO_BIN_EXE_tcpf");
    let role = |name: &str, args: &[&str]| {
        let own = keys.map(|k| k.join(format!("{name}.pem")).display().to_string());
        let mut args: Vec<&str> = [args, settings].concat();
        if let Some(own) = &own {
            args.extend(["--credential", own]);
        }
        let args = credentialed(&args);
        logged(logs, name, tcpf, &args.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let mut fleet = Vec::new();
    let endpoint = match keys {
        Some(keys) => {
            let (router, endpoint) = listening(|e| {
                let args = ["router", "--credential", keys.to_str().unwrap(), "-l", &over_tls(e)];
                logged(logs, "router", tcpf, &args)
            });
            let endpoint = over_tls(&endpoint);
            fleet.push(Reaper(router));
            fleet.push(Reaper(role("planner", &["planner", mission, "-e", &endpoint])));
            endpoint
        }
        None => {
            let (planner, endpoint) = listening(|e| role("planner", &["planner", mission, "-l", e]));
            fleet.push(Reaper(planner));
            endpoint
        }
    };
    let e = endpoint.as_str();
    fleet.push(Reaper(role(
        "world",
        &["world", mission, "-e", e, "--recorders", "1", "--vehicles", "1"],
    )));
    for id in ["1", "2"] {
        fleet.push(Reaper(role(
            &format!("agent-{id}"),
            &["agent", mission, "--id", id, "-e", e],
        )));
    }
    (fleet, endpoint)
}

/// A fleet by hand whose vehicle 2 another program played (`vehicle`, logging into
/// `logs/vehicle.log`), recorded into `out` by `tcpf record`, which said `recorded`: the recording
/// succeeded, both vehicles arrived within a second of each other with a coordination error under
/// 1 s, and the program stopped by itself within 10 s of the end. The run's summary.
pub fn assert_played_together(recorded: &Output, logs: &Path, out: &Path, vehicle: &mut Reaper) -> Value {
    let log = |name: &str| std::fs::read_to_string(logs.join(format!("{name}.log"))).unwrap_or_default();
    assert!(
        recorded.status.success(),
        "{}\nvehicle: {}\nworld: {}",
        text(recorded),
        log("vehicle"),
        log("world")
    );
    let s = summary(out);
    let a = arrivals(&s);
    let error = s["max_coordination_error"].as_f64().unwrap();
    assert!(error < 1.0, "coordination error {error:.3} s; arrivals {a:?}");
    assert!((a[0] - a[1]).abs() < 1.0, "arrivals {a:?}");
    let stopped = wait_exit(
        &mut vehicle.0,
        Duration::from_secs(10),
        "the vehicle's program, at the end",
    );
    assert_eq!(stopped, Some(0), "{}", log("vehicle"));
    assert!(log("world").contains("simulating vehicles [1]"), "{}", log("world"));
    s
}

/// The liveliness tokens under `key` that `session` finds now (a query that waits at most 5 s).
pub async fn tokens(session: &zenoh::Session, key: &str) -> Vec<String> {
    let replies = session
        .liveliness()
        .get(key)
        .timeout(Duration::from_secs(5))
        .await
        .unwrap();
    let mut known = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        known.extend(reply.result().ok().map(|s| s.key_expr().to_string()));
    }
    known
}
