//! `tcpf bench`: each figure of a mission's speed beside a baseline measured in the same
//! invocation (this machine is shared and noisy: only the ratios mean something). The plan on
//! every core beside one; the in-process fleet beside the world alone; a lockstep tick as
//! processes beside a raw Zenoh round trip, direct and through a router; the fleet's memory and
//! sockets beside as many idle Zenoh clients.

use std::convert::Infallible;
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

use tcpf_bus::claim::Rivals;
use tcpf_bus::clock::Monotonic;
use tcpf_bus::driver::{drive, Wiring};
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::outlet::Outlet;
use tcpf_bus::presence::presence;
use tcpf_bus::rejected::Rejected;
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_bus::subscribe::{subscribe, subscribe_with};
use tcpf_core::mission::{Mission, VehicleKind};
use tcpf_core::model::planner::Plan;
use tcpf_core::msg::{Gamma, Sample, PROTOCOL_VERSION};
use tcpf_core::outputs::summary::Summary;
use tcpf_core::roles::machine::Machine;
use tcpf_core::roles::sim::{world_alone, world_and_laws, Fleet};
use tcpf_core::time::Moment;
use tcpf_report::provenance::Invocation;
use tcpf_report::rundir::RunDir;

use crate::error::{failed, Context, Result};
use crate::launcher;
use tokio::process::{Child, Command};

const PING: &str = "tcpf/bench/ping";
const PONG: &str = "tcpf/bench/pong";

/// How long the pong process may take to come up, and to answer one probe: bounds on a process
/// that does not, not part of any figure.
const PONG_UP: Duration = Duration::from_secs(30);
const PONG_ANSWER: Duration = Duration::from_secs(5);
/// How long the idle clients may take to come up, all of them.
const IDLE_UP: Duration = Duration::from_secs(120);
/// How long the idle clients are left before their memory is read, to settle as a running fleet
/// has (their start's buffers freed).
const IDLE_SETTLE: Duration = Duration::from_secs(1);
/// How often a running fleet's memory is read: often enough to see a fleet of a second at least
/// once (the memory is read from `/proc`, which tells no one when it changes).
const FLEET_SAMPLE: Duration = Duration::from_millis(100);
/// How long the last reading may take once the fleet has gone.
const FLEET_SAMPLED: Duration = Duration::from_secs(2);
/// The provenance of the bench's own runs: none, as they are removed unread once measured.
const SCRATCH: Invocation = Invocation {
    command: Vec::new(),
    version: String::new(),
    commit: None,
};

fn probe(tick: u64) -> Gamma {
    Gamma {
        version: PROTOCOL_VERSION,
        tick,
        from: 0,
        sample: Some(Sample {
            t: tick as f64,
            gamma: tick as f64,
            gamma_dot: 1.0,
            position: [0.0, 0.0],
        }),
        busy: false,
    }
}

/// The echo side: answers every ping with a pong of the same payload until `count` echoes, in
/// Zenoh's callback, as an agent answers a state: the round trip is Zenoh's and the sockets'
/// alone. `id` names its token, so that a fleet of idle ones can be counted.
pub async fn pong(zenoh: &ZenohArgs, count: u64, id: u32) -> Result<()> {
    let session = zenoh.open().await?;
    let rejected = Rejected::default();
    let out = Outlet::new(&session, PONG.into()).await?;
    let (echoed, mut echoes) = tokio::sync::mpsc::unbounded_channel();
    let _sub = subscribe_with::<Gamma>(&session, PING, &rejected, move |_, ping| {
        let _ = echoed.send(out.put_now(&ping));
    })
    .await?;
    let token = Keys::new("bench").alive(Role::Agent, id);
    let _token = session
        .liveliness()
        .declare_token(token)
        .await
        .map_err(|e| failed!("{e}"))?;
    for _ in 0..count {
        let Some(echo) = echoes.recv().await else { break };
        echo?;
    }
    let _ = session.close().await;
    Ok(())
}

/// A `tcpf pong` child with `args`, run as an agent is (its Zenoh threads), which dies with this
/// process.
fn start_pong(exe: &Path, args: &[&str]) -> Result<Child> {
    let mut pong = Command::new(exe);
    pong.arg("pong")
        .args(args)
        .envs(crate::launcher::child_runtime(Role::Agent))
        .stdout(Stdio::null())
        .kill_on_drop(true);
    crate::launcher::dies_with_this_process(&mut pong);
    Ok(pong.spawn().context("cannot start tcpf pong")?)
}

/// Round-trip times to a `tcpf pong` child on a loopback port, sorted: peer to peer, or with
/// `routed` both sides clients of a router in this process: the path of a γ, which the world
/// passes from one agent to another. Both sides run open: a bare Zenoh baseline, on loopback for
/// the seconds it takes.
pub async fn ping(exe: &Path, count: u64, routed: bool) -> Result<Vec<Duration>> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?.port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let router = if routed {
        Some(open_router(&endpoint).await?)
    } else {
        None
    };
    let session = if routed {
        client(&endpoint).open().await?
    } else {
        ZenohArgs {
            listen: vec![endpoint.clone()],
            open: true,
            ..ZenohArgs::default()
        }
        .open()
        .await?
    };
    let mode = if routed { "client" } else { "peer" };
    let rejected = Rejected::default();
    let (_sub, mut pongs) = subscribe::<Gamma>(&session, PONG, &rejected).await?;
    let (_alive, mut alive) = presence(&session, &Keys::new("bench")).await?;
    let out = Outlet::new(&session, PING.into()).await?;
    let mut child = start_pong(
        exe,
        &[
            "--count",
            &(count + 100).to_string(),
            "-e",
            &endpoint,
            "--mode",
            mode,
            "--open",
        ],
    )?;
    let deadline = tokio::time::Instant::now() + PONG_UP;
    while tokio::time::timeout_at(deadline, alive.recv())
        .await
        .map_err(|_| failed!("pong never came up"))?
        .is_none_or(|p| !p.alive)
    {}
    let mut times = Vec::with_capacity(count as usize);
    for k in 0..count + 100 {
        let start = Instant::now();
        out.put(&probe(k)).await?;
        loop {
            let p = tokio::time::timeout(PONG_ANSWER, pongs.recv())
                .await
                .map_err(|_| failed!("no pong"))?;
            if p.is_some_and(|p| p.message.tick == k) {
                break;
            }
        }
        // The first hundred warm the route up.
        if k >= 100 {
            times.push(start.elapsed());
        }
    }
    let _ = child.wait().await;
    let _ = session.close().await;
    if let Some(router) = router {
        let _ = router.close().await;
    }
    times.sort_unstable();
    Ok(times)
}

/// How long the in-process fleet took, and its baselines.
pub struct InProcess {
    /// Vehicle-steps of the run.
    pub steps: u64,
    pub fleet: Duration,
    /// The world alone, integrating as many vehicles for as many ticks with constant commands.
    pub world: Duration,
    /// The world with the agents' laws alone: the fleet's arithmetic, without its machines.
    pub laws: Duration,
}

/// The in-process fleet and its baselines, each the best of `repeat`.
pub fn in_process(mission: &Mission, plan: &Plan, repeat: usize) -> InProcess {
    let best = |f: &mut dyn FnMut()| {
        (0..repeat)
            .map(|_| {
                let start = Instant::now();
                f();
                start.elapsed()
            })
            .min()
            .unwrap_or_default()
    };
    let mut ticks = 0;
    let fleet = best(&mut || ticks = std::hint::black_box(Fleet::new(mission, plan).run(|_, _| {})).ticks);
    let world = best(&mut || {
        std::hint::black_box(world_alone(mission, plan, ticks));
    });
    let laws = best(&mut || {
        std::hint::black_box(world_and_laws(mission, plan, ticks));
    });
    InProcess {
        steps: ticks * plan.vehicles.len() as u64,
        fleet,
        world,
        laws,
    }
}

/// Runs per second of a sweep of `runs` seeds of the mission in-process on every core (into
/// `dir`: rows, tables, figures), of the same sweep keeping its series (`--series`), and of the
/// same runs as bare `Fleet::run`s on as many threads (the baseline): what the sweep itself
/// costs per run.
pub struct SweepRates {
    pub swept: f64,
    pub series: f64,
    pub bare: f64,
}

pub fn sweep_rates(mission: &Mission, plan: &Plan, runs: u64, dir: &Path) -> Result<SweepRates> {
    use std::sync::atomic::{AtomicU64, Ordering};
    use tcpf_report::sweep::{figures::Look, Design, Grid, Sweep};
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let bare = Instant::now();
    let next = AtomicU64::new(0);
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| loop {
                let seed = next.fetch_add(1, Ordering::Relaxed) + 1;
                if seed > runs {
                    break;
                }
                let mut m = mission.clone();
                m.mission.seed = seed;
                std::hint::black_box(Fleet::new(&m, plan).run(|_, _| {}));
            });
        }
    });
    let bare = bare.elapsed();
    let sweep = |dir: &Path, series: bool| -> Result<Duration> {
        let swept = Instant::now();
        let design = Design {
            mission: mission.mission.name.clone(),
            grid: Grid {
                params: Vec::new(),
                seeds: runs,
                seed_start: 1,
            },
            shard: None,
            mode: "in-process".into(),
            clearance: mission.planner.clearance,
        };
        let grid = design.grid.clone();
        let mut sweep = Sweep::create(Some(dir), &mission.to_toml(), Default::default(), design)?;
        sweep.draw(series, Look::default())?;
        let every = crate::sweep::Runs {
            grid,
            missions: vec![mission.clone()],
        };
        crate::sweep::run_in_process(&every, std::slice::from_ref(plan), threads, &mut sweep)?;
        sweep.finish()?;
        Ok(swept.elapsed())
    };
    let swept = sweep(&dir.join("rows"), false)?;
    let series = sweep(&dir.join("series"), true)?;
    let rate = |d: Duration| runs as f64 / d.as_secs_f64();
    Ok(SweepRates {
        swept: rate(swept),
        series: rate(series),
        bare: rate(bare),
    })
}

/// The mission's fleet in-process with every vehicle kinematic, then with every vehicle a
/// MEDUSA (MODEL D22), each the best of `repeat`: what the plant, thrusters and inner loops cost
/// beside the kinematic vehicle.
pub fn vehicle_models(mission: &Mission, plan: &Plan, repeat: usize) -> [(VehicleKind, InProcess); 2] {
    [VehicleKind::Kinematic, VehicleKind::Medusa].map(|kind| {
        let mut every = mission.clone();
        every.vehicle_model.kind = kind;
        every.vehicles.iter_mut().for_each(|v| v.vehicle_model = None);
        (kind, in_process(&every, plan, repeat))
    })
}

/// Ten lanes with event-triggered γ in-process on acoustic modems, and the same without a modem
/// (the baseline), each the best of `repeat`: what the physical layer (MODEL D23) costs a tick,
/// and per frame it judged.
pub struct ModemCost {
    pub ticks: u64,
    /// Frames judged, busy instants included: `messages.csv`'s rows.
    pub frames: u64,
    pub with: Duration,
    pub without: Duration,
}

pub fn modem_cost(repeat: usize) -> Result<ModemCost> {
    let text = tcpf_core::mission::generate::lanes(10, 0.0);
    let mission = |sets: &[&str]| {
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        tcpf_core::mission::parse("lanes10.toml", &text, &sets).map_err(|e| failed!("{e}"))
    };
    let plain = mission(&["comms.trigger=\"event\""])?;
    let modem = mission(&["comms.trigger=\"event\"", "comms.modem={}"])?;
    let plan = tcpf_core::model::planner::plan(&plain).map_err(|e| failed!("{e}"))?;
    let mut frames = 0;
    let mut ticks = 0;
    let mut best = |m: &Mission, count: bool| {
        (0..repeat)
            .map(|_| {
                let start = Instant::now();
                let mut judged = 0;
                let r = Fleet::new(m, &plan)
                    .run(|_, c| judged += c.iter().flatten().map(|c| c.receptions.len()).sum::<usize>());
                if count {
                    (frames, ticks) = (judged as u64, r.ticks);
                }
                start.elapsed()
            })
            .min()
            .unwrap_or_default()
    };
    let with = best(&modem, true);
    let without = best(&plain, false);
    Ok(ModemCost {
        ticks,
        frames,
        with,
        without,
    })
}

/// A router listening on `endpoint`, with nothing else.
async fn open_router(endpoint: &str) -> Result<zenoh::Session> {
    Ok(ZenohArgs {
        listen: vec![endpoint.into()],
        mode: Some("router".into()),
        open: true,
        ..ZenohArgs::default()
    }
    .open()
    .await?)
}

fn client(endpoint: &str) -> ZenohArgs {
    ZenohArgs {
        connect: vec![endpoint.into()],
        mode: Some("client".into()),
        open: true,
        ..ZenohArgs::default()
    }
}

/// Memory and sockets of a set of processes at one instant.
#[derive(Debug, Clone, Copy, Default)]
pub struct Footprint {
    pub processes: usize,
    /// Resident set, KiB: counts the binary's code in every process that maps it.
    pub rss_kib: u64,
    /// Proportional set, KiB: shared pages divided among their sharers, so it adds up.
    pub pss_kib: u64,
    pub sockets: usize,
}

impl Footprint {
    /// The children of this process whose command line holds `role` as its first argument.
    pub fn of_children(role: &str) -> Footprint {
        let me = std::process::id();
        let mut f = Footprint::default();
        let Ok(dir) = std::fs::read_dir("/proc") else {
            return f;
        };
        for pid in dir
            .flatten()
            .filter_map(|e| e.file_name().to_str()?.parse::<u32>().ok())
        {
            let proc = format!("/proc/{pid}");
            let parent = std::fs::read_to_string(format!("{proc}/stat"))
                .ok()
                .and_then(|s| s.rsplit(')').next()?.split_whitespace().nth(1)?.parse::<u32>().ok());
            let args = std::fs::read(format!("{proc}/cmdline")).unwrap_or_default();
            let first = args.split(|&b| b == 0).nth(1).unwrap_or_default();
            if parent != Some(me) || first != role.as_bytes() {
                continue;
            }
            let field = |file: &str, name: &str| {
                std::fs::read_to_string(format!("{proc}/{file}")).ok().and_then(|s| {
                    s.lines()
                        .find(|l| l.starts_with(name))?
                        .split_whitespace()
                        .nth(1)?
                        .parse::<u64>()
                        .ok()
                })
            };
            f.processes += 1;
            f.rss_kib += field("status", "VmRSS:").unwrap_or(0);
            f.pss_kib += field("smaps_rollup", "Pss:").unwrap_or(0);
            f.sockets += std::fs::read_dir(format!("{proc}/fd")).map_or(0, |fds| {
                fds.flatten()
                    .filter(|fd| {
                        std::fs::read_link(fd.path()).is_ok_and(|l| l.to_string_lossy().starts_with("socket:"))
                    })
                    .count()
            });
        }
        f
    }

    /// Per process, MiB: (RSS, PSS).
    pub fn per_process_mib(&self) -> (f64, f64) {
        let n = self.processes.max(1) as f64;
        (self.rss_kib as f64 / 1024.0 / n, self.pss_kib as f64 / 1024.0 / n)
    }
}

/// Reading the footprint of a role's processes from `/proc`, which tells no one when it changes:
/// once, `after` a while (`Readings::once`), or every `period` while they run, keeping the last
/// reading of all of them, until they are gone (`Readings::until_gone`).
struct Readings {
    period: Option<f64>,
    next: Option<Moment>,
    due: bool,
    kept: Footprint,
    done: bool,
}

/// Read the footprint now.
struct Read;

impl Readings {
    fn once(after: Duration, now: Moment) -> Readings {
        Readings {
            period: None,
            next: Some(now + after),
            due: false,
            kept: Footprint::default(),
            done: false,
        }
    }

    fn until_gone(period: Duration, now: Moment) -> Readings {
        Readings {
            period: Some(period.as_secs_f64()),
            ..Readings::once(period, now)
        }
    }
}

impl Machine for Readings {
    type Input = Footprint;
    type Output = Read;
    type Exit = Footprint;

    fn handle(&mut self, read: Footprint, now: Moment) {
        let Some(period) = self.period else {
            self.kept = read;
            self.done = true;
            return;
        };
        // Once its agents have let go of the code of their start (`agent/src/footprint.rs`),
        // before the first leaves.
        if read.processes >= self.kept.processes && read.processes > 0 {
            self.kept = read;
        }
        if read.processes == 0 && self.kept.processes > 0 {
            self.done = true;
        } else {
            self.next = Some(now + period);
        }
    }

    fn poll_timeout(&self) -> Option<Moment> {
        self.next
    }

    fn handle_timeout(&mut self, _: Moment, _: Moment) {
        self.next = None;
        self.due = true;
    }

    fn poll_output(&mut self) -> Option<Read> {
        std::mem::take(&mut self.due).then_some(Read)
    }

    fn poll_exit(&mut self) -> Option<Footprint> {
        self.done.then(|| std::mem::take(&mut self.kept))
    }
}

/// Reads the footprint of the children that are `role` processes, off the runtime's threads.
struct Reader {
    role: &'static str,
}

impl Wiring<Readings> for Reader {
    type Error = Infallible;

    async fn next(&mut self) -> Footprint {
        std::future::pending().await
    }

    async fn perform(&mut self, Read: Read, _: &Readings) -> Result<Option<Footprint>, Infallible> {
        let role = self.role;
        let read = tokio::task::spawn_blocking(move || Footprint::of_children(role)).await;
        Ok(Some(read.unwrap_or_default()))
    }
}

/// The footprint of the children that are `role` processes, read as `readings` says.
async fn read(role: &'static str, mut readings: Readings) -> Footprint {
    let Ok(footprint) = drive(&mut readings, &mut Reader { role }, Monotonic::start()).await;
    footprint
}

/// The footprint of `n` idle Zenoh clients (`tcpf pong`, one subscription, one publisher, one
/// token) of one router: what a fleet of agents costs before it does anything.
pub async fn idle_fleet(exe: &Path, n: usize) -> Result<Footprint> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?.port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let router = open_router(&endpoint).await?;
    let (_alive, mut alive) = presence(&router, &Keys::new("bench")).await?;
    let mut children = Vec::with_capacity(n);
    for id in 0..n {
        let id = id.to_string();
        children.push(start_pong(
            exe,
            &[
                "--count", "1", "--id", &id, "-e", &endpoint, "--mode", "client", "--open",
            ],
        )?);
    }
    let mut up = std::collections::BTreeSet::new();
    let deadline = tokio::time::Instant::now() + IDLE_UP;
    while up.len() < n {
        match tokio::time::timeout_at(deadline, alive.recv()).await {
            Ok(Some(p)) if p.alive => {
                up.insert(p.id);
            }
            Ok(Some(_)) => {}
            _ => return Err(failed!("only {} of {n} idle clients came up", up.len()).into()),
        }
    }
    let footprint = read("pong", Readings::once(IDLE_SETTLE, Monotonic::start().now())).await;
    for mut c in children {
        let _ = c.start_kill();
        let _ = c.wait().await;
    }
    let _ = router.close().await;
    Ok(footprint)
}

/// What a bench is asked beyond its mission: how many round trips to time, and which fleets of
/// `tcpf gen lanes` to run as processes besides.
#[derive(Debug, Clone, Copy)]
pub struct Asked<'a> {
    pub count: u64,
    pub fleets: &'a [u32],
}

/// Measures `mission`'s lockstep fleet, saying each figure beside its baseline as soon as it has
/// both (`planned`: how long the plan took on every core); `false` if a signal stopped it, which
/// leaves no child and no scratch directory.
pub async fn measure(
    mission: &Mission,
    plan: &Plan,
    planned: Duration,
    exe: &Path,
    what: Asked<'_>,
    shutdown: &mut Shutdown,
    mut say: impl FnMut(String),
) -> Result<bool> {
    let Asked { count, fleets } = what;
    let seconds = |d: Duration| d.as_secs_f64();
    let started = Instant::now();
    let _ = tcpf_core::model::planner::plan(mission);
    let on_one = started.elapsed();
    say(format!(
        "plan ({} vehicles): {:.3} s on {} cores, {:.3} s on one (baseline): {:.2}x",
        plan.vehicles.len(),
        seconds(planned),
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        seconds(on_one),
        seconds(on_one) / seconds(planned)
    ));
    let took = in_process(mission, plan, 3);
    let rate = |d: Duration| took.steps as f64 / seconds(d) / 1e6;
    say(format!(
        "in-process: {:.2} M vehicle-steps/s; the world alone (baseline) {:.2} M/s: {:.2}x; \
         the world and the laws alone {:.2} M/s: {:.2}x",
        rate(took.fleet),
        rate(took.world),
        rate(took.fleet) / rate(took.world),
        rate(took.laws),
        rate(took.fleet) / rate(took.laws)
    ));
    let [(_, kinematic), (_, medusa)] = vehicle_models(mission, plan, 3);
    let per_second = |t: &InProcess| t.steps as f64 / seconds(t.fleet) / 1e6;
    say(format!(
        "in-process on MEDUSA (every vehicle): {:.2} M vehicle-steps/s; kinematic (baseline) {:.2} M/s: {:.2}x",
        per_second(&medusa),
        per_second(&kinematic),
        per_second(&medusa) / per_second(&kinematic)
    ));

    let modem = modem_cost(7)?;
    let tick_us = |d: Duration| seconds(d) * 1e6 / modem.ticks as f64;
    let extra = seconds(modem.with) - seconds(modem.without);
    say(format!(
        "in-process, 10 lanes with events on acoustic modems: {:.1} µs a tick; without a modem (baseline) {:.1} µs: {:.2}x; \
         the layer {:.2} µs per frame judged ({} frames), {:.1} % of a tick",
        tick_us(modem.with),
        tick_us(modem.without),
        seconds(modem.with) / seconds(modem.without),
        extra * 1e6 / modem.frames.max(1) as f64,
        modem.frames,
        100.0 * extra / seconds(modem.with)
    ));

    // This process's own scratch directory: one a killed bench of the same pid left is stale.
    let scratch = std::env::temp_dir().join(format!("tcpf-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    let runs = 200;
    let SweepRates { swept, series, bare } = sweep_rates(mission, plan, runs, &scratch.join("sweep"))?;
    let _ = std::fs::remove_dir_all(&scratch);
    say(format!(
        "sweep of {runs} seeds in-process: {swept:.1} runs/s; the same runs as bare Fleet::run on as many threads (baseline) {bare:.1} runs/s: {:.2}x; \
         keeping e(t) and d(t) (--series) {series:.1} runs/s: {:.2}x the sweep without",
        swept / bare,
        series / swept
    ));
    let measured = processes(mission, plan, exe, count, &scratch, shutdown).await;
    let _ = std::fs::remove_dir_all(&scratch);
    let Some(p) = measured? else {
        return Ok(false);
    };
    let median = |t: &[Duration]| t[t.len() / 2].as_secs_f64() * 1e6;
    let tick = p.fleet.tick_wall_time_us;
    say(format!(
        "zenoh round trip between two processes: median {:.1} µs direct, {:.1} µs through a router",
        median(&p.direct),
        median(&p.routed)
    ));
    say(format!(
        "lockstep tick ({} vehicles, {} ticks, best of {ROUNDS} runs): {:.1} µs; tick / round trip: {:.2} direct, {:.2} through a router",
        plan.vehicles.len(),
        p.fleet.results.ticks,
        tick,
        tick / median(&p.direct),
        tick / median(&p.routed)
    ));
    say(format!(
        "lockstep tick with a certificate per role (mutual TLS) and the world's access rules: {:.1} µs; with a user and password per role over TCP {:.1} µs; with neither (baseline) {:.1} µs: {:.2}x and {:.2}x",
        tick,
        p.passwords.tick_wall_time_us,
        p.plain.tick_wall_time_us,
        tick / p.plain.tick_wall_time_us,
        p.passwords.tick_wall_time_us / p.plain.tick_wall_time_us
    ));
    say(format!(
        "lockstep tick with --ros2 (the world and every agent as ROS 2 nodes, no subscriber): {:.1} µs; / without it: {:.2}",
        p.ros2.tick_wall_time_us,
        p.ros2.tick_wall_time_us / tick
    ));
    // A short mission's wall time is much its start: the tick says how fast the fleet runs.
    say(format!(
        "simulated / wall time: {:.1} by the tick, {:.1} from the start to the end",
        mission.mission.control_period / (tick * 1e-6),
        p.fleet.speedup()
    ));
    let first = |s: &Summary| s.first_tick_s.unwrap_or(f64::NAN);
    say(format!(
        "start-up: the first tick {:.3} s after the launch; with the world and agents claiming their roles as roles started by hand do (baseline) {:.3} s: {:.2}x",
        first(&p.fleet),
        first(&p.settled),
        first(&p.fleet) / first(&p.settled)
    ));
    let (rss, pss) = p.running.per_process_mib();
    let (idle_rss, idle_pss) = p.idle.per_process_mib();
    say(format!(
        "per agent: RSS {rss:.1} MiB, PSS {pss:.1} MiB; an idle Zenoh client (baseline): RSS {idle_rss:.1} MiB, PSS {idle_pss:.1} MiB"
    ));
    say(format!(
        "agents' sockets: {} for {} agents; idle clients' (baseline): {}",
        p.running.sockets, p.running.processes, p.idle.sockets
    ));
    let mut ticks = Vec::with_capacity(fleets.len());
    for &vehicles in fleets {
        let ran = lanes(vehicles, exe, &scratch, shutdown).await;
        let _ = std::fs::remove_dir_all(&scratch);
        let Some((run, period)) = ran? else {
            return Ok(false);
        };
        let tick = run.tick_wall_time_us;
        say(format!(
            "{vehicles} lanes as processes ({} ticks, best of {ROUNDS} runs): a tick {tick:.1} µs, {:.1} µs an agent; \
             simulated / wall time {:.2} by the tick, {:.2} from the start to the end; the first tick {:.3} s after the launch; \
             tick / round trip (baseline, above): {:.2}",
            run.results.ticks,
            tick / f64::from(vehicles),
            period / (tick * 1e-6),
            run.speedup(),
            first(&run),
            tick / median(&p.direct)
        ));
        ticks.push((vehicles, tick));
    }
    if let [(few, small), .., (many, large)] = ticks[..] {
        say(format!(
            "from {few} to {many} lanes: the tick {:.2}x for {:.1}x the agents",
            large / small,
            f64::from(many) / f64::from(few)
        ));
    }
    Ok(true)
}

/// Keeps `run` as `best` if its tick is the shorter.
fn keep_faster(best: &mut Option<Summary>, run: Summary) {
    if best
        .as_ref()
        .is_none_or(|b| run.tick_wall_time_us < b.tick_wall_time_us)
    {
        *best = Some(run);
    }
}

/// `tcpf gen lanes --vehicles N`'s fleet as processes, the best of `ROUNDS` runs by the tick;
/// with its control period; `None` if a signal stopped it.
async fn lanes(vehicles: u32, exe: &Path, scratch: &Path, shutdown: &mut Shutdown) -> Result<Option<(Summary, f64)>> {
    let name = format!("lanes{vehicles}.toml");
    let mission = tcpf_core::mission::parse(&name, &tcpf_core::mission::generate::lanes(vehicles, 0.2), &[])
        .map_err(|e| failed!("{e}"))?;
    let plan = tcpf_core::model::planner::plan(&mission).map_err(|e| failed!("{name}: {e}"))?;
    let mut best: Option<Summary> = None;
    for round in 0..ROUNDS {
        let out = scratch.join(format!("lanes-{vehicles}-{round}"));
        let Some(run) = variant(&mission, &plan, exe, &out, launcher::Options::default(), shutdown).await? else {
            return Ok(None);
        };
        keep_faster(&mut best, run);
    }
    Ok(best.map(|b| (b, mission.mission.control_period)))
}

/// Runs of each variant of the fleet whose ticks are compared, taken in turn, the best of them
/// kept, none beside the footprint's sampler: on a shared machine of two cores one run alone, or
/// one sharing its cores with a scan of /proc, said the access rules cost 1.4x one time and
/// 0.86x the next.
const ROUNDS: usize = 3;

/// What the bench measures of processes: round trips, the fleet, the fleet speaking ROS 2, and
/// the footprints of its agents and of as many idle clients.
struct Processes {
    direct: Vec<Duration>,
    routed: Vec<Duration>,
    fleet: Summary,
    ros2: Summary,
    /// The fleet whose world and agents claimed their roles as roles started by hand do.
    settled: Summary,
    /// The fleet with a user and password per role instead of a certificate.
    passwords: Summary,
    /// The fleet with no credential and no access rules.
    plain: Summary,
    running: Footprint,
    idle: Footprint,
}

/// The fleet run with `options` in run directory `out`; `None` if a signal stopped it.
async fn variant(
    mission: &Mission,
    plan: &Plan,
    exe: &Path,
    out: &Path,
    options: launcher::Options,
    shutdown: &mut Shutdown,
) -> Result<Option<Summary>> {
    let dir = RunDir::create(Some(out), mission, SCRATCH)?;
    let Some(summary) = shutdown.unless(launcher::run(mission, plan, &dir, exe, options)).await else {
        return Ok(None);
    };
    let summary = summary?;
    Ok((!summary.interrupted).then_some(summary))
}

/// `None` if a signal stopped it: its children go (dropped, they are killed).
async fn processes(
    mission: &Mission,
    plan: &Plan,
    exe: &Path,
    count: u64,
    scratch: &Path,
    shutdown: &mut Shutdown,
) -> Result<Option<Processes>> {
    let Some(direct) = shutdown.unless(ping(exe, count, false)).await else {
        return Ok(None);
    };
    let Some(routed) = shutdown.unless(ping(exe, count, true)).await else {
        return Ok(None);
    };
    let dir = RunDir::create(Some(scratch), mission, SCRATCH)?;
    // The fleet's footprint as it runs: the last reading of the whole fleet.
    let sampling = tokio::spawn(read(
        "agent",
        Readings::until_gone(FLEET_SAMPLE, Monotonic::start().now()),
    ));
    let sampled = launcher::run(mission, plan, &dir, exe, launcher::Options::default()).await?;
    let running = tokio::time::timeout(FLEET_SAMPLED, sampling).await;
    let running = running.ok().and_then(Result::ok).unwrap_or_default();
    if sampled.interrupted {
        return Ok(None);
    }
    // Beside the fleet as it runs by default, each the best of `ROUNDS`: the same speaking ROS 2
    // beside its own protocol (odometry and /clock every tick) with no ROS 2 subscriber, what
    // --ros2 costs the fleet itself; with a password per role over TCP; and with no credential
    // and no access rules.
    let variants = [
        launcher::Options::default(),
        launcher::Options {
            ros2: Some(0),
            announce: false,
            ..launcher::Options::default()
        },
        launcher::Options {
            links: launcher::Links::Passwords,
            ..launcher::Options::default()
        },
        launcher::Options {
            links: launcher::Links::Plain,
            ..launcher::Options::default()
        },
    ];
    let mut best: [Option<Summary>; 4] = Default::default();
    for round in 0..ROUNDS {
        for (k, options) in variants.iter().enumerate() {
            let out = scratch.join(format!("variant-{k}-{round}"));
            let Some(run) = variant(mission, plan, exe, &out, options.clone(), shutdown).await? else {
                return Ok(None);
            };
            keep_faster(&mut best[k], run);
        }
    }
    let [Some(fleet), Some(ros2), Some(passwords), Some(plain)] = best else {
        return Err(failed!("a variant of the fleet did not run").into());
    };
    let settled = launcher::Options {
        rivals: Rivals::Possible,
        ..launcher::Options::default()
    };
    let Some(settled) = variant(mission, plan, exe, &scratch.join("settled"), settled, shutdown).await? else {
        return Ok(None);
    };
    let Some(idle) = shutdown.unless(idle_fleet(exe, plan.vehicles.len())).await else {
        return Ok(None);
    };
    Ok(Some(Processes {
        direct: direct?,
        routed: routed?,
        fleet,
        ros2,
        settled,
        passwords,
        plain,
        running,
        idle: idle?,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn of(processes: usize, rss_kib: u64) -> Footprint {
        Footprint {
            processes,
            rss_kib,
            ..Footprint::default()
        }
    }

    /// Runs `readings` on a clock that jumps to each wake-up, each reading the next of `found`:
    /// what it kept, and when it stopped.
    fn run(mut readings: Readings, found: &[Footprint]) -> (Footprint, f64) {
        let mut found = found.iter();
        loop {
            let at = readings.poll_timeout().expect("a reading is due");
            readings.handle_timeout(at, at);
            while readings.poll_output().is_some() {
                readings.handle(*found.next().expect("read no more than found"), at);
            }
            if let Some(kept) = readings.poll_exit() {
                return (kept, at.secs());
            }
        }
    }

    #[test]
    fn a_running_fleet_is_read_until_it_is_gone_its_last_whole_reading_kept() {
        let found = [of(0, 0), of(3, 30), of(5, 60), of(5, 50), of(2, 20), of(0, 0)];
        let (kept, at) = run(Readings::until_gone(FLEET_SAMPLE, Moment::default()), &found);
        assert_eq!((kept.processes, kept.rss_kib), (5, 50));
        assert!((at - 0.6).abs() < 1e-9, "read every 100 ms, six times: {at}");
    }

    #[test]
    fn idle_clients_are_read_once_after_they_settle() {
        let (kept, at) = run(Readings::once(IDLE_SETTLE, Moment::default()), &[of(4, 40)]);
        assert_eq!((kept.processes, kept.rss_kib), (4, 40));
        assert_eq!(at, 1.0);
    }
}
