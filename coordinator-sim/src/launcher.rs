//! `tcpf run` as processes: one planner, one world and one agent per vehicle, children of the same
//! binary on a loopback port of their own; the launcher records them and stops them all.

use std::convert::Infallible;
use std::fs::File;
use std::net::SocketAddr;
use std::path::Path;
use std::process::Stdio;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use tcpf_bus::acl::Identity;
use tcpf_bus::claim::Rivals;
use tcpf_bus::clock::Monotonic;
use tcpf_bus::driver::{drive, Wiring};
use tcpf_bus::error::Error as BusError;
use tcpf_bus::keys::Role;
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_bus::waits::Timeouts as RoleTimeouts;
use tcpf_core::mission::{ClockKind, Mission, Ros2Config};
use tcpf_core::model::planner::Plan;
use tcpf_core::msg::Report;
use tokio::process::Command;

pub use crate::access::Links;
use crate::access::ROS2_CONFIG;
use crate::error::{failed, Context, Error, Result, RunFailed};
use crate::progress::Ticks;
use crate::recording::Recording;
use tcpf_core::outputs::summary::{ChildSummary, Closing, Mode, Summary};
use tcpf_core::roles::machine::Machine;
use tcpf_core::roles::supervisor::{
    Child, Exit, Failure, Input, Outcome, Output, Recorded, Supervision, Supervisor, Timeouts, When,
};
use tcpf_report::rundir::RunDir;
use tokio::signal::unix::Signal;

/// Zenoh's threads in a lockstep agent or planner (unless the user set ZENOH_RUNTIME): one,
/// instead of six that hand every message to each other. Such a child is a client and routes
/// nothing, so nothing it runs waits on a queue only that thread would drain. Measured on 10
/// agents: a tick 12 % cheaper, and fewer threads' stacks per agent. A realtime child keeps
/// Zenoh's defaults, with which its timing was measured.
pub const CHILD_RUNTIME: &str =
    "(rx: (handover: app), tx: (handover: app), acc: (handover: app), net: (handover: app), app: (worker_threads: 1))";
/// Zenoh's threads in a lockstep world, the run's router: one, as a child's, but for the thread
/// that writes to the sockets. A router that forwards with congestion control *block* waits for
/// a full queue to drain, and on one thread it would wait for itself: the recorder falling
/// behind by a few batches stopped a run of 10 agents for seconds, or for good.
pub const WORLD_RUNTIME: &str =
    "(rx: (handover: app), acc: (handover: app), net: (handover: app), app: (worker_threads: 1))";
/// Zenoh's threads in the launcher of a lockstep run, and in `tcpf bench`, whose routed round trip
/// passes through a router of its own: two that each take a message from one socket to the next,
/// instead of a receiving thread that hands it to a sending one (when the launcher was the
/// fleet's router: 10 agents, a tick 780 -> 660 us).
pub const LAUNCHER_RUNTIME: &str =
    "(rx: (handover: app), tx: (handover: app), acc: (handover: app), net: (handover: app), app: (worker_threads: 2))";
/// Whether this process set ZENOH_RUNTIME itself (`launcher_runtime`), not the user.
static OWN_RUNTIME: AtomicBool = AtomicBool::new(false);

/// Gives this process, about to launch a lockstep fleet, `LAUNCHER_RUNTIME` unless the user
/// chose Zenoh's threads. Zenoh reads the variable once, at its first session, and offers no
/// other way to set its threads; setting a variable is safe only while no other thread may read
/// the environment, so it is set only while the process has one thread (Linux says how many), and
/// otherwise left alone: the fleet then runs on Zenoh's default threads, a little slower.
pub fn launcher_runtime() {
    if std::env::var_os("ZENOH_RUNTIME").is_none() && threads() == Some(1) {
        std::env::set_var("ZENOH_RUNTIME", LAUNCHER_RUNTIME);
        OWN_RUNTIME.store(true, Ordering::Relaxed);
    }
}

/// How many threads this process has.
fn threads() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    status
        .lines()
        .find_map(|l| l.strip_prefix("Threads:")?.trim().parse().ok())
}

/// The ZENOH_RUNTIME a lockstep child of `role` is given, unless the user chose one.
pub fn child_runtime(role: Role) -> Option<(&'static str, &'static str)> {
    let chosen = std::env::var_os("ZENOH_RUNTIME").is_some() && !OWN_RUNTIME.load(Ordering::Relaxed);
    let runtime = if role == Role::World {
        WORLD_RUNTIME
    } else {
        CHILD_RUNTIME
    };
    (!chosen).then_some(("ZENOH_RUNTIME", runtime))
}
struct Process {
    role: Role,
    id: u32,
    pid: u32,
    child: tokio::process::Child,
    exit_code: Option<Option<i32>>,
    /// The signal that ended it, if one did.
    signal: Option<i32>,
    args: Vec<String>,
}

impl Process {
    fn poll(&mut self) -> Option<Option<i32>> {
        if self.exit_code.is_none() {
            if let Ok(Some(status)) = self.child.try_wait() {
                self.exited(status);
            }
        }
        self.exit_code
    }

    /// How it ended, once it has.
    fn exit(&self) -> Exit {
        Exit {
            code: self.exit_code.flatten(),
            signal: self.signal,
        }
    }

    fn child(&self) -> Child {
        Child {
            role: self.role,
            id: self.id,
        }
    }

    fn exited(&mut self, status: std::process::ExitStatus) {
        use std::os::unix::process::ExitStatusExt;
        self.exit_code = Some(status.code());
        self.signal = status.signal();
    }
}

/// The exit report of this very process (a role started again reports once per life).
fn report_of<'a>(recording: &'a Recording, c: &Process) -> Option<&'a Report> {
    recording
        .reports()
        .iter()
        .find(|r| r.role == c.role.as_str() && r.id == c.id && r.pid == c.pid)
}

/// A port on 127.0.0.1 that was free a moment ago.
fn free_port() -> Result<u16> {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").context("no free port on 127.0.0.1")?;
    Ok(listener.local_addr()?.port())
}

/// The last error a role printed before it exited, from its log.
fn last_error(log: &Path) -> Option<String> {
    let text = std::fs::read_to_string(log).ok()?;
    let line = text.lines().rev().find(|l| l.starts_with("error: "))?;
    Some(line["error: ".len()..].to_string())
}

/// Why the run fails: `child` (the world, the planner, or an agent before the first tick)
/// exited `when`, with its code or the signal that killed it, in its own last words where its
/// log has them.
fn died(dir: &RunDir, child: Child, exit: Exit, when: When) -> String {
    Failure::Died {
        child,
        exit,
        when,
        last_words: last_error(&dir.path.join("logs").join(child.log())),
    }
    .to_string()
}

/// A child must never outlive the process that started it, even one killed with SIGKILL: the
/// kernel kills the child when its parent goes.
pub(crate) fn dies_with_this_process(command: &mut Command) {
    let parent = std::process::id();
    // SAFETY: between fork and exec the closure makes only async-signal-safe calls (prctl,
    // getppid, _exit) and allocates nothing.
    unsafe {
        command.pre_exec(move || {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            // The parent died before the line above: nobody would kill us.
            if libc::getppid() as u32 != parent {
                libc::_exit(1);
            }
            Ok(())
        });
    }
}

fn spawn(exe: &Path, dir: &RunDir, role: Role, id: Option<u32>, args: &[String], lockstep: bool) -> Result<Process> {
    let logs = dir.path.join("logs");
    let (who, name) = match id {
        Some(id) => (format!("{role} {id}"), format!("{role}-{id}.log")),
        None => (role.to_string(), format!("{role}.log")),
    };
    std::fs::create_dir_all(&logs).with_context(|| format!("cannot start {who}: cannot create {}", logs.display()))?;
    // Appended to: an agent started again writes on in the same log.
    let log = File::options()
        .create(true)
        .append(true)
        .open(logs.join(&name))
        .with_context(|| format!("cannot start {who}: cannot create logs/{name}"))?;
    let output = log
        .try_clone()
        .with_context(|| format!("cannot start {who}: cannot share logs/{name}"))?;
    let mut command = Command::new(exe);
    command.arg(role.as_str()).args(args);
    if lockstep {
        command.envs(child_runtime(role));
    }
    if let Some(id) = id {
        command.args(["--id", &id.to_string()]);
    }
    // A terminal's Ctrl-C goes to its foreground process group: with the children in it, a world
    // stopped by the same keystroke could publish its end before the launcher heard the signal,
    // and the run read as completed, not arrived: exit 1, "interrupted": false. In a group of
    // their own they hear it from the launcher, which tells each to stop.
    command.process_group(0);
    // A lockstep agent is a batch job: the tick waits for every agent, not for any one soon.
    // Under SCHED_BATCH a woken agent does not preempt the thread that woke it, so the world
    // writes a tick's states to every agent before they run, instead of being preempted at
    // each write (50 agents: the world's writer preempted 8.9 -> 0.5 times a tick, the tick
    // 2.20 -> 1.95 ms, six runs each interleaved). Not in realtime, where an agent waits on its
    // own clock; not for a launcher the user gave a policy of their own, which children keep.
    let batch = lockstep && role == Role::Agent;
    // SAFETY: between fork and exec the closure makes only async-signal-safe calls
    // (sched_getscheduler, sched_setscheduler) and allocates nothing.
    unsafe {
        command.pre_exec(move || {
            if batch && libc::sched_getscheduler(0) == libc::SCHED_OTHER {
                let param = libc::sched_param { sched_priority: 0 };
                // Refused (a sandbox), the agent only runs as before.
                libc::sched_setscheduler(0, libc::SCHED_BATCH, &param);
            }
            Ok(())
        });
    }
    dies_with_this_process(&mut command);
    let child = command
        .stdin(Stdio::null())
        .stdout(Stdio::from(output))
        .stderr(Stdio::from(log))
        .kill_on_drop(true)
        .spawn()
        .with_context(|| format!("cannot start {} {who}", exe.display()))?;
    let pid = child
        .id()
        .ok_or_else(|| failed!("cannot start {who}: it exited at once"))?;
    Ok(Process {
        role,
        id: id.unwrap_or(0),
        pid,
        child,
        exit_code: None,
        signal: None,
        args: args.to_vec(),
    })
}

/// How long one attempt to reach the world waits: between attempts the launcher looks whether
/// the world died and whether it was told to stop.
const ATTEMPT_MS: u64 = 200;

/// This process's session, a client of the world once it listens, which it must within
/// `startup`. The world may fail first (a port taken since it was found free): then its own
/// words say why.
async fn connect(
    config: &Path,
    links: Links,
    world: &mut Process,
    dir: &RunDir,
    startup: Duration,
    shutdown: &mut Shutdown,
) -> Result<zenoh::Session> {
    let mut config = ZenohArgs {
        config: Some(config.to_path_buf()),
        open: links == Links::Plain,
        ..ZenohArgs::default()
    }
    .config()?;
    // Zenoh's open blocks its thread until it connects or times out: short attempts, so that
    // neither a dead world nor Ctrl-C waits out zenoh.json5's minute.
    config
        .insert_json5("connect/timeout_ms", &ATTEMPT_MS.to_string())
        .map_err(|e| failed!("zenoh connect/timeout_ms: {e}"))?;
    let started = Instant::now();
    loop {
        let attempt = config.clone();
        let mut opening = tokio::spawn(async move { zenoh::open(attempt).await });
        tokio::select! {
            opened = &mut opening => if let Ok(Ok(session)) = opened {
                return Ok(session);
            },
            _ = shutdown.recv() => return Err(BusError::Interrupted("while the world was starting").into()),
            ended = world.child.wait() => {
                if let Ok(status) = ended {
                    world.exited(status);
                }
                return Err(Error::Failed(died(dir, world.child(), world.exit(), When::AsItStarted)));
            }
        }
        if started.elapsed() > startup {
            return Err(failed!(
                "the world did not listen within {} s; see logs/world.log",
                startup.as_secs_f64()
            )
            .into());
        }
    }
}

/// How `tcpf run` runs its children.
#[derive(Debug, Clone)]
pub struct Options {
    /// Serve the run to Foxglove live.
    pub live: Option<SocketAddr>,
    /// The roles' waits: the world is given its wait for every agent and recorder (`startup`)
    /// and for an agent's command of a tick (`command`).
    pub roles: RoleTimeouts,
    /// Start an agent that died again, so that it rejoins.
    pub restart: bool,
    /// Recorders from elsewhere the run waits for, besides its own.
    pub recorders: usize,
    /// The ROS 2 domain the world speaks rmw_zenoh on, if any.
    pub ros2: Option<u32>,
    /// A `tcp/` endpoint where the world also listens with no credential, for ROS 2 nodes that
    /// only listen (`--ros2-open`).
    pub ros2_open: Option<String>,
    /// `Rivals::Possible` makes the world and agents claim their roles as roles started by hand
    /// do, waiting for contemporaries that cannot exist here: the baseline `tcpf bench` sets
    /// a run's start-up beside.
    pub rivals: Rivals,
    /// How each role proves which it is (a certificate by default); `Links::Plain` runs the fleet
    /// with no credential and no access rules: the baseline `tcpf bench` sets a run's tick beside.
    pub links: Links,
    /// Whether to say on standard error how a ROS 2 shell joins the run (with `ros2`); `tcpf
    /// bench`'s runs are joined by nobody.
    pub announce: bool,
}

impl Default for Options {
    fn default() -> Options {
        Options {
            live: None,
            roles: RoleTimeouts::default(),
            restart: false,
            recorders: 0,
            ros2: None,
            ros2_open: None,
            rivals: Rivals::None,
            links: Links::Certificates,
            announce: true,
        }
    }
}

/// The supervisor's view of this run: the world's waits, and the wall period of its clock.
fn supervision(mission: &Mission, roles: &RoleTimeouts, restart: bool) -> Supervision {
    Supervision {
        restart,
        lockstep: mission.mission.clock == ClockKind::Lockstep,
        startup_timeout_s: roles.startup.as_secs_f64(),
        command_timeout_s: roles.command.as_secs_f64(),
        wall_period_s: mission.mission.control_period / mission.mission.time_scale,
        timeouts: Timeouts::default(),
    }
}

/// Kills the children that have not exited, and waits for them.
async fn stop(children: &mut [Process]) {
    for c in children.iter_mut() {
        if c.poll().is_none() {
            let _ = c.child.start_kill();
            if let Ok(status) = c.child.wait().await {
                c.exited(status);
            }
        }
    }
}

/// A run stopped before its first tick by `e` (a signal, a world that could not start, an agent
/// that could not be started): its children are stopped, and its run directory is whole even
/// so, a summary that says what stopped it with the telemetry's headers and the report, as a run
/// that did start leaves. Returns the error to give: `e` if a signal, else `RunFailed`.
async fn unstarted(
    mission: &Mission,
    plan: &Plan,
    dir: &RunDir,
    children: &mut [Process],
    begun: Instant,
    e: Error,
) -> Error {
    stop(children).await;
    let interrupted = e.interrupted();
    let summary = Summary::before_the_first_tick(
        mission,
        plan.t_f,
        interrupted,
        (!interrupted).then(|| format!("{e:#}")),
        begun.elapsed().as_secs_f64(),
        children.iter().map(|c| child_summary(c, None)).collect(),
    );
    // The (empty) telemetry, whose start writes a provisional summary; then, whatever became of
    // it, the summary that replaces that one; then the report made of both.
    let telemetry = dir
        .telemetry(mission, plan, Mode::Processes, None, None)
        .and_then(|t| t.finish());
    let written = dir
        .write_summary(&summary)
        .and(telemetry)
        .and_then(|()| tcpf_report::report::write(&dir.path, &tcpf_report::report::Options::default()));
    if let Err(unwritten) = written {
        tracing::warn!("the run directory could not be written whole: {unwritten:#}");
    }
    if interrupted {
        return e;
    }
    RunFailed {
        why: format!("{e:#}"),
        dir: dir.path.clone(),
    }
    .into()
}

/// Ctrl-Z (SIGTSTP) as a shell's job control would have it, for a fleet whose children are in
/// process groups of their own (so that the terminal's Ctrl-C reaches them only through this
/// process): every child stops, then this process, and when `fg` continues it, every child
/// continues. Stopped alone, the launcher's recorder read nothing while the world went on, and
/// the world cut it off after a few seconds: the run finished unrecorded.
fn suspend_with(children: &[Process]) {
    let signal_all = |signal| {
        for c in children.iter().filter(|c| c.exit_code.is_none()) {
            // SAFETY: kill(2) on the process group of a child not yet reaped (its own group,
            // `process_group(0)`), hence not reused.
            unsafe { libc::kill(-(c.pid as libc::pid_t), signal) };
        }
    };
    tracing::info!("stopped (Ctrl-Z): the fleet stops with this process, and goes on with it");
    signal_all(libc::SIGSTOP);
    // SAFETY: raise(3) stops this whole process, as SIGTSTP's default action would have; it
    // returns once a SIGCONT (the shell's `fg` or `bg`) continues it.
    unsafe { libc::raise(libc::SIGSTOP) };
    signal_all(libc::SIGCONT);
}

/// A child as the summary lists it, with what its exit report said if it sent one.
fn child_summary(c: &Process, report: Option<&Report>) -> ChildSummary {
    ChildSummary {
        role: c.role.as_str().into(),
        id: c.id,
        pid: c.pid,
        exit_code: c.exit_code.flatten(),
        signal: c.signal,
        rejected: report.map(|r| r.rejected.total()),
        reported_pid: report.map(|r| r.pid),
    }
}

/// How to join the run, said as it can be joined: where the world listens, and with ROS 2 the
/// lines a ROS 2 shell needs (rmw_zenoh reads its session configuration once per process, and
/// the `ros2` CLI's daemon keeps the one it started with).
fn joining(endpoint: &str, dir: &Path, ros2: Option<&Ros2Config>, open: Option<&str>) -> String {
    let mut text = format!("the fleet's router, the world, listens at {endpoint}");
    let Some(ros2) = ros2 else {
        return text;
    };
    let domain = ros2.domain;
    text.push_str(&format!(
        ". A ROS 2 shell (rmw_zenoh) joins it on domain {domain} with the run's certificate for listening:\n  \
         export RMW_IMPLEMENTATION=rmw_zenoh_cpp ROS_DOMAIN_ID={domain}\n  \
         export ZENOH_SESSION_CONFIG_URI={}\n  \
         ros2 daemon stop   # the CLI's daemon keeps the configuration it started with\n\
         to play vehicle <id> instead: ZENOH_SESSION_CONFIG_URI={}",
        dir.join(ROS2_CONFIG).display(),
        dir.join("vehicle-<id>.json5").display(),
    ));
    if let Some(open) = open {
        text.push_str(&format!(
            "\nOPEN to listeners: the world also listens at {open} with no credential, where a stock ROS 2 node connects with no configuration (RMW_IMPLEMENTATION=rmw_zenoh_cpp ROS_DOMAIN_ID={domain}); anything that reaches it may hear the whole fleet, and may say nothing"
        ));
    }
    text
}

/// Runs the mission as processes and writes the run directory. `exe` is the tcpf binary.
pub async fn run(mission: &Mission, plan: &Plan, dir: &RunDir, exe: &Path, options: Options) -> Result<Summary> {
    let Options {
        live,
        roles,
        restart,
        recorders,
        ros2,
        ros2_open,
        rivals,
        links,
        announce,
    } = options;
    let begun = Instant::now();
    let mut shutdown = Shutdown::new()?;
    let mut suspend = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::from_raw(libc::SIGTSTP))
        .context("cannot handle SIGTSTP (Ctrl-Z)")?;
    dir.write_mission(mission, tcpf_core::outputs::summary::Mode::Processes)?;
    dir.write_plan(plan)?;
    let mission_file = dir.path.join("mission.toml").display().to_string();
    let endpoint = format!("{}/127.0.0.1:{}", links.protocol(), free_port()?);
    // How another tool (a recorder, a testbed bridge, a probe) joins the running fleet: as a role,
    // with its configuration, which only the run directory's owner can read.
    let graph = mission.ros2(ros2);
    let configs = crate::access::create(
        &dir.path,
        &endpoint,
        mission,
        graph.as_ref(),
        links,
        ros2_open.as_deref(),
    )?;
    let lockstep = mission.mission.clock == ClockKind::Lockstep;
    let as_role = |identity| {
        let mut args = vec![
            mission_file.clone(),
            "-c".to_string(),
            configs.of(identity).display().to_string(),
        ];
        if links == Links::Plain {
            args.push("--open".into());
        }
        args
    };
    let mut world_args = as_role(Identity::World);
    world_args.extend([
        "--recorders".to_string(),
        (1 + recorders).to_string(),
        "--command-timeout".to_string(),
        roles.command.as_secs_f64().to_string(),
        "--startup-timeout".to_string(),
        roles.startup.as_secs_f64().to_string(),
    ]);
    if restart {
        let rejoin = Timeouts::default().rejoin_s;
        world_args.extend(["--rejoin-timeout".to_string(), rejoin.to_string()]);
    }
    let mut agent_args = Vec::new();
    // The only world, and the only agent of each vehicle, this launcher runs at a time.
    if rivals == Rivals::None {
        world_args.push("--no-rivals".into());
        agent_args.push("--no-rivals".into());
    }
    if let Some(domain) = ros2 {
        world_args.extend(["--ros2".to_string(), domain.to_string()]);
        agent_args.extend(["--ros2".to_string(), domain.to_string()]);
    }
    // The world is the run's router: every other process, this one too, is its client. The
    // planner plans while the world starts (a client, it waits for the world to listen): the
    // world cannot start before the recorder below is there, so nothing is missed, and the plan
    // is not on the path to the first tick.
    let mut children = Vec::with_capacity(mission.vehicles.len() + 2);
    for (role, args) in [(Role::World, &world_args), (Role::Planner, &as_role(Identity::Planner))] {
        match spawn(exe, dir, role, None, args, lockstep) {
            Ok(child) => children.push(child),
            Err(e) => return Err(unstarted(mission, plan, dir, &mut children, begun, e).await),
        }
    }
    let session = match connect(
        &configs.of(Identity::Recorder),
        links,
        &mut children[0],
        dir,
        roles.startup,
        &mut shutdown,
    )
    .await
    {
        Ok(session) => session,
        Err(e) => return Err(unstarted(mission, plan, dir, &mut children, begun, e).await),
    };
    let ready = async {
        crate::access::announce(&dir.path, &endpoint)?;
        if announce {
            eprintln!(
                "{}",
                joining(&endpoint, &dir.path, graph.as_ref(), ros2_open.as_deref())
            );
        }
        if recorders > 0 {
            eprintln!(
                "waiting up to {} s for {recorders} more recorder(s) before the run starts: join with `tcpf record {} -c {} --out <dir>`, or your own tool with that zenoh.json5",
                roles.startup.as_secs_f64(),
                dir.path.join("mission.toml").display(),
                configs.of(Identity::Recorder).display()
            );
        }
        Recording::start(
            &session,
            mission,
            plan.t_f,
            dir.telemetry(mission, plan, Mode::Processes, live, graph.as_ref())?,
            &roles,
        )
        .await
    };
    let mut recording = match ready.await {
        Ok(recording) => recording,
        Err(e) => {
            let _ = session.close().await;
            return Err(unstarted(mission, plan, dir, &mut children, begun, e).await);
        }
    };
    // From here a failure is the recording's to close, as one in the run is.
    let spawned = async {
        // The recorder's subscriptions reach the world before its token, on the same link: the
        // world cannot start a tick the recorder would miss.
        recording.declare().await?;
        // Listed as before the world routed: the planner, the world, the agents.
        children.swap(0, 1);
        for v in &mission.vehicles {
            let args = [as_role(Identity::Agent(v.id)), agent_args.clone()].concat();
            children.push(spawn(exe, dir, Role::Agent, Some(v.id), &args, lockstep)?);
        }
        Ok::<_, Error>(())
    }
    .await;
    let progress = Ticks::new(mission);
    // A run whose agents could not all start lasted from the launch, as one stopped earlier does.
    let started = if spawned.is_ok() { Instant::now() } else { begun };
    let clock = Monotonic::start();
    let mut supervisor = Supervisor::new(
        supervision(mission, &roles, restart),
        children.iter().map(Process::child),
        clock.now(),
    );
    if let Err(e) = spawned {
        supervisor.handle(Input::Failed(format!("{e:#}")), clock.now());
    }
    let mut fleet = Fleet {
        exe,
        dir,
        lockstep,
        started,
        children: &mut children,
        retired: Vec::new(),
        warnings: Vec::new(),
        recording: &mut recording,
        progress,
        shutdown: &mut shutdown,
        suspend: &mut suspend,
        outcome: None,
        ended_at: None,
    };
    let Ok(()) = drive(&mut supervisor, &mut fleet, clock).await;
    let Fleet {
        retired,
        warnings,
        outcome,
        ended_at,
        ..
    } = fleet;
    let outcome = outcome.expect("a supervisor is done only once the run is over");
    let wall_time_s = ended_at.unwrap_or_else(|| started.elapsed()).as_secs_f64();
    let _ = session.close().await;

    let children: Vec<ChildSummary> = retired
        .iter()
        .chain(&children)
        .map(|c| child_summary(c, report_of(&recording, c)))
        .collect();
    let ended = matches!(outcome, Outcome::Completed);
    let first_tick_s = recording.first_tick().map(|at| at.duration_since(begun).as_secs_f64());
    let summary = recording.close(
        mission,
        dir,
        Closing {
            ended,
            interrupted: matches!(outcome, Outcome::Interrupted),
            failure: match &outcome {
                Outcome::Failed(why) => Some(why.to_string()),
                _ => None,
            },
            wall_time_s,
            first_tick_s,
            children,
            restarts: supervisor.restarts().to_vec(),
            warnings,
        },
    )?;
    match outcome {
        Outcome::Failed(why) => Err(RunFailed {
            why: why.to_string(),
            dir: dir.path.clone(),
        }
        .into()),
        _ => Ok(summary),
    }
}

/// The launcher's process for its supervisor: the recording's steps and the signals as inputs;
/// the children it starts again, tells to stop and kills; their exits, looked at.
struct Fleet<'a> {
    exe: &'a Path,
    dir: &'a RunDir,
    lockstep: bool,
    /// When the run began, as its wall time counts.
    started: Instant,
    children: &'a mut Vec<Process>,
    /// Agents that died and were started again: their exits are part of the run's record.
    retired: Vec<Process>,
    /// What went wrong without failing the run.
    warnings: Vec<String>,
    recording: &'a mut Recording,
    progress: Ticks,
    shutdown: &'a mut Shutdown,
    suspend: &'a mut Signal,
    outcome: Option<Outcome>,
    ended_at: Option<Duration>,
}

impl Wiring<Supervisor> for Fleet<'_> {
    type Error = Infallible;

    async fn next(&mut self) -> Input {
        let running = self.outcome.is_none();
        tokio::select! {
            r = self.recording.step() => match r {
                Err(e) if running => Input::Failed(format!("the recorder failed: {e:#}")),
                Err(e) => {
                    tracing::error!("recorder: {e:#}; writing what was recorded");
                    Input::Failed(format!("{e:#}"))
                }
                Ok(()) => {
                    let recording = &self.recording;
                    if running {
                        self.progress.set(recording.ticks());
                    }
                    Input::Recorded(Recorded {
                        ticks: recording.ticks(),
                        ended: recording.ended(),
                        complete: recording.complete(),
                        lost: recording.lost(),
                        refused_ahead: recording.rejected.totals().future,
                    })
                }
            },
            _ = self.shutdown.recv(), if running => Input::Interrupted,
            _ = self.suspend.recv(), if running => {
                suspend_with(self.children);
                Input::Continued
            }
        }
    }

    async fn perform(&mut self, output: Output, _: &Supervisor) -> Result<Option<Input>, Infallible> {
        Ok(match output {
            Output::Restart { child, exit } => {
                let c = &mut self.children[child];
                tracing::warn!("agent {} died ({exit}); starting it again", c.id);
                match spawn(self.exe, self.dir, Role::Agent, Some(c.id), &c.args, self.lockstep) {
                    Ok(again) => {
                        self.retired.push(std::mem::replace(c, again));
                        Some(Input::Restarted(child))
                    }
                    Err(e) => Some(Input::Failed(format!("agent {} died ({exit}) and {e:#}", c.id))),
                }
            }
            Output::PlannerGone { child, exit, ticks } => {
                let gone = format!(
                    "{} (at tick {ticks}); the run went on without it, but an agent started again could not have fetched its path",
                    died(self.dir, self.children[child].child(), exit, When::AfterServingThePaths)
                );
                tracing::warn!("{gone}");
                self.warnings.push(gone);
                None
            }
            Output::Over(over) => {
                self.ended_at = Some(self.started.elapsed());
                self.progress.finish();
                self.outcome = Some(match over {
                    Outcome::Failed(Failure::Died { child, exit, when, .. }) => {
                        Outcome::Failed(Failure::Other(died(self.dir, child, exit, when)))
                    }
                    over => over,
                });
                None
            }
            Output::Terminate => {
                for c in self.children.iter_mut() {
                    if c.poll().is_none() {
                        // SAFETY: kill(2) on the pid of a child not yet reaped, hence not reused.
                        unsafe { libc::kill(c.pid as libc::pid_t, libc::SIGTERM) };
                    }
                }
                None
            }
            Output::Kill => {
                stop(self.children).await;
                None
            }
        })
    }

    /// Zenoh gives no event for a child's exit: the children are looked at as the supervisor
    /// wakes, every `Timeouts::check_s` at the most.
    fn looked(&mut self) -> Vec<Input> {
        let mut found = Vec::new();
        for (index, c) in self.children.iter_mut().enumerate() {
            if c.exit_code.is_none() && c.poll().is_some() {
                found.push(Input::Exited(index, c.exit()));
            }
            if c.exit_code.is_some() && report_of(self.recording, c).is_some() {
                found.push(Input::Reported(index));
            }
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mission(overrides: &[&str]) -> Mission {
        let text = include_str!("../../configs/paper/b-current.toml");
        let overrides: Vec<String> = overrides.iter().map(|o| o.to_string()).collect();
        tcpf_core::mission::parse("b-current.toml", text, &overrides).unwrap()
    }

    #[test]
    fn a_run_stalls_only_after_what_the_world_waits_for_on_purpose() {
        let stall = |mission: &Mission, command| {
            let roles = RoleTimeouts {
                command,
                ..RoleTimeouts::default()
            };
            supervision(mission, &roles, false).stall_limit_s()
        };
        let b = mission(&[]);
        assert_eq!(stall(&b, RoleTimeouts::default().command), 60.0);
        assert_eq!(stall(&b, Duration::from_secs(120)), 130.0);
        // A wall period of 50 s (a control period of 0.05 s at the slowest time scale): a tick
        // every 50 s is no stall.
        let slow = mission(&[
            "mission.clock=\"realtime\"",
            "mission.time_scale=0.001",
            "mission.control_period=0.05",
        ]);
        assert_eq!(stall(&slow, RoleTimeouts::default().command), 110.0);
    }

    #[test]
    fn zenohs_threads_are_chosen_only_while_the_process_has_one_thread() {
        // The test harness runs tests on threads of their own: more than one.
        assert!(threads().is_some_and(|n| n > 1), "{:?}", threads());
        let before = std::env::var_os("ZENOH_RUNTIME");
        launcher_runtime();
        assert_eq!(std::env::var_os("ZENOH_RUNTIME"), before, "left alone");
    }
}
