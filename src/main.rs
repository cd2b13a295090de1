//! `tcpf`: time-coordinated path following for fleets of vehicles. One binary, every role.

use std::io::IsTerminal;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::anyhow;
use clap::{Args, Parser, Subcommand};
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_coordinator::{bench, inprocess, launcher, planner_node, planning, sweep};
use tcpf_core::mission::{self, Mission};
use tcpf_core::planner::Plan;
use tcpf_report::{rundir::RunDir, table};

#[derive(Parser)]
#[command(
    name = "tcpf",
    version,
    about = "Time-coordinated path following for fleets of vehicles"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Args)]
struct MissionArgs {
    /// Mission file (TOML).
    file: PathBuf,
    /// Override a mission key: `section.key=value`, `section.table.key=value`, or
    /// `vehicle.<id>.key=value`.
    #[arg(long = "set", value_name = "K=V")]
    set: Vec<String>,
    /// The `set`s that stand for other flags, and those flags as typed: what an error names.
    #[arg(skip)]
    flags: Vec<(String, String)>,
}

/// Which clock the fleet runs on; on top of the mission's `[mission] clock` and `time_scale`.
#[derive(Args, Clone)]
struct ClockArgs {
    /// lockstep (the world waits for every command: reproducible) or realtime (the wall clock).
    #[arg(long, value_parser = ["lockstep", "realtime"])]
    clock: Option<String>,
    /// Realtime: simulated seconds per wall second (1: real time).
    #[arg(long, value_name = "X", value_parser = time_scale, allow_hyphen_values = true)]
    time_scale: Option<f64>,
}

impl ClockArgs {
    /// The mission keys these flags stand for, each with its flag. `--clock lockstep` alone
    /// also sets the time scale back to 1, which only the realtime clock may change.
    fn sets(&self) -> Vec<(String, String)> {
        let mut sets = Vec::new();
        if let Some(c) = &self.clock {
            sets.push((format!("mission.clock={c}"), format!("--clock {c}")));
            if c == "lockstep" && self.time_scale.is_none() {
                sets.push(("mission.time_scale=1.0".into(), format!("--clock {c}")));
            }
        }
        if let Some(x) = self.time_scale {
            sets.push((format!("mission.time_scale={x:?}"), format!("--time-scale {x}")));
        }
        sets
    }
}

/// What `tcpf run` does when an agent dies.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Restart {
    /// Its vehicle is lost and drifts.
    Never,
    /// The agent is started again and rejoins.
    OnFailure,
}

#[derive(Subcommand)]
enum Generated {
    /// Vehicles in parallel lanes 4 m apart on a ring, against a cross current (ring5 grown).
    Lanes {
        /// How many vehicles (one lane each).
        #[arg(long, value_parser = clap::value_parser!(u32).range(2..=i64::from(mission::generate::MAX_VEHICLES)))]
        vehicles: u32,
        /// Loss probability of every link.
        #[arg(long, default_value_t = 0.2, value_parser = probability)]
        loss: f64,
    },
}

/// A time scale on the command line, within the mission's bound.
fn time_scale(text: &str) -> Result<f64, String> {
    let (min, max) = (mission::MIN_TIME_SCALE, mission::MAX_TIME_SCALE);
    match text.parse::<f64>() {
        Ok(x) if (min..=max).contains(&x) => Ok(x),
        _ => Err(format!(
            "{text}: give simulated seconds per wall second, in [{min}, {max}]"
        )),
    }
}

/// The most recorders a run waits for: each is a process on the bus, and a count beyond any
/// fleet's is a typo (18446744073709551615, plus the launcher's own, wrapped to none at all).
const MAX_RECORDERS: u64 = 64;

fn recorders() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new().range(0..=MAX_RECORDERS)
}

/// A probability on the command line: a number in [0, 1].
fn probability(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(p) if (0.0..=1.0).contains(&p) => Ok(p),
        _ => Err(format!("{text}: give a probability in [0, 1]")),
    }
}

#[derive(Subcommand)]
enum Command {
    /// Launch a mission, record it and write the run directory.
    Run {
        #[command(flatten)]
        mission: MissionArgs,
        #[command(flatten)]
        clock: ClockArgs,
        /// Start a dead agent again (it rejoins the run), or never (its vehicle is lost).
        #[arg(long, value_enum, default_value = "never")]
        restart: Restart,
        /// Run directory (default runs/<mission>-<timestamp>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Drive every machine in one loop instead of one process per role (the reference).
        #[arg(long)]
        in_process: bool,
        /// Mission seed (overrides mission.seed); a TOML integer, so at most 2^63 − 1.
        #[arg(long, value_parser = clap::value_parser!(u64).range(..=i64::MAX as u64))]
        seed: Option<u64>,
        /// Serve the run to Foxglove live over its WebSocket protocol (default 127.0.0.1:8765).
        #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:8765")]
        live: Option<SocketAddr>,
        /// Seconds a tick waits for a live agent's command; then its vehicle is lost (silent).
        /// More than the agents' stale timeout (3 s). [default: 10]
        #[arg(long, value_parser = seconds, allow_hyphen_values = true)]
        command_timeout: Option<Duration>,
        /// Start the run only once N more recorders have joined: `tcpf record` or tools of your
        /// own, with the run directory's `zenoh.json5` (-c).
        #[arg(long, value_name = "N", default_value_t = 0, value_parser = recorders())]
        recorders: usize,
        /// Seconds the world waits for every agent and recorder before it gives up and says who
        /// is missing. [default: 60]
        #[arg(long, value_parser = seconds, allow_hyphen_values = true)]
        startup_timeout: Option<Duration>,
    },
    /// Solve the trajectory generation problem and print the plan.
    Plan {
        #[command(flatten)]
        mission: MissionArgs,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Fault-injection experiment: every (value, seed) pair, summarised per value.
    #[command(group(clap::ArgGroup::new("values").required(true).args(["loss", "param"])))]
    Sweep {
        #[command(flatten)]
        mission: MissionArgs,
        /// Loss probabilities to sweep (comms.loss), e.g. 0,0.3,0.6,0.9.
        #[arg(long, value_delimiter = ',')]
        loss: Vec<String>,
        /// Any mission key instead: KEY=V1,V2,...
        #[arg(long, value_name = "KEY=V1,V2,...")]
        param: Option<String>,
        /// Seeds 1..=N for every value (each a run's --seed).
        #[arg(long, value_parser = clap::value_parser!(u64).range(1..=i64::MAX as u64))]
        seeds: u64,
        /// Run each as a real fleet of processes (one after the other) instead of in-process.
        #[arg(long)]
        processes: bool,
        /// Output directory (default runs/<mission>-sweep-<timestamp>/).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Print a generated mission file, for fleets of any size.
    Gen {
        #[command(subcommand)]
        mission: Generated,
    },
    /// Write (again) a run directory's report.html from its recorded files.
    Report {
        /// The run directory.
        dir: PathBuf,
    },
    /// Every speed figure beside its baseline: the plan, the in-process fleet, the lockstep tick
    /// against a raw Zenoh round trip, the agents' memory and sockets.
    Bench {
        #[command(flatten)]
        mission: MissionArgs,
        /// Round trips to time.
        #[arg(long, default_value_t = 2000, value_parser = clap::value_parser!(u64).range(1..))]
        count: u64,
    },
    /// The echo side of `tcpf bench`.
    #[command(hide = true)]
    Pong {
        #[command(flatten)]
        zenoh: ZenohArgs,
        #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
        count: u64,
        /// Names its liveliness token.
        #[arg(long, default_value_t = 0)]
        id: u32,
    },
    /// A Zenoh router for a testbed: every role connects to it (configs/zenoh/).
    Router {
        #[command(flatten)]
        zenoh: ZenohArgs,
    },
    /// Role: plan and serve every vehicle's path.
    Planner {
        #[command(flatten)]
        mission: MissionArgs,
        #[command(flatten)]
        zenoh: ZenohArgs,
        /// Accepted like every role's, so that one command line serves all: paths do not
        /// depend on the clock.
        #[command(flatten)]
        clock: ClockArgs,
    },
    /// Role: the world, which integrates the vehicles and keeps the fleet's clock.
    World {
        #[command(flatten)]
        mission: MissionArgs,
        #[command(flatten)]
        zenoh: ZenohArgs,
        #[command(flatten)]
        clock: ClockArgs,
        /// Realtime: simulate only these vehicles (ids, comma-separated); other processes play
        /// the others by publishing their State and taking their Command.
        #[arg(long, value_delimiter = ',', value_name = "IDS")]
        vehicles: Option<Vec<u32>>,
        /// Lockstep: seconds a tick waits for a gone agent to come back before its vehicle is
        /// lost (default: lost at once).
        #[arg(long, value_parser = seconds, allow_hyphen_values = true)]
        rejoin_timeout: Option<Duration>,
        /// Recorders to wait for before the first tick.
        #[arg(long, default_value_t = 0, value_parser = recorders())]
        recorders: usize,
        /// Seconds to wait, from the start, for the plan, the agents and the recorders.
        #[arg(long, default_value = "60", value_parser = seconds, allow_hyphen_values = true)]
        startup_timeout: Duration,
        /// Seconds a tick waits for a live agent's command; then its vehicle is lost (silent).
        #[arg(long, default_value = "10", value_parser = seconds, allow_hyphen_values = true)]
        command_timeout: Duration,
    },
    /// Role: record a fleet started by hand (start its world with --recorders 1).
    Record {
        #[command(flatten)]
        mission: MissionArgs,
        #[command(flatten)]
        zenoh: ZenohArgs,
        #[command(flatten)]
        clock: ClockArgs,
        /// Run directory (default runs/<mission>-<timestamp>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Serve the run to Foxglove live over its WebSocket protocol (default 127.0.0.1:8765).
        #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:8765")]
        live: Option<SocketAddr>,
        /// Seconds to wait for the world.
        #[arg(long, default_value = "60", value_parser = seconds, allow_hyphen_values = true)]
        startup_timeout: Duration,
    },
    /// Role: the agent of one vehicle.
    Agent {
        #[command(flatten)]
        mission: MissionArgs,
        #[command(flatten)]
        zenoh: ZenohArgs,
        #[command(flatten)]
        clock: ClockArgs,
        /// The vehicle's id.
        #[arg(long)]
        id: u32,
        /// Seconds to wait for the planner, the world and the neighbours.
        #[arg(long, default_value = "60", value_parser = seconds, allow_hyphen_values = true)]
        startup_timeout: Duration,
        /// Seconds after which a silent neighbour stops being counted.
        #[arg(long, default_value = "3", value_parser = seconds, allow_hyphen_values = true)]
        stale_timeout: Duration,
    },
}

/// Writes to stdout. A reader that went away (`tcpf gen lanes … | head`) ends the output, as it
/// wanted, rather than the process with a panic; any other failure to write (a full disk under
/// `> lanes.toml`) fails the command.
fn out(text: std::fmt::Arguments) -> Result<(), Failure> {
    use std::io::Write;
    match std::io::stdout().lock().write_fmt(text) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(Failure::Failed(anyhow::anyhow!("writing to stdout: {e}")))
        }
        _ => Ok(()),
    }
}

/// `print!` through `out`, in a function that returns a `Failure`.
macro_rules! say {
    ($($arg:tt)*) => { out(format_args!($($arg)*))? };
}

/// `println!` through `out`.
macro_rules! sayln {
    ($($arg:tt)*) => { out(format_args!("{}\n", format_args!($($arg)*)))? };
}

/// How a command failed: exit code 2 for bad input, 1 for a mission or run that failed.
enum Failure {
    Input(anyhow::Error),
    Failed(anyhow::Error),
    Interrupted(anyhow::Error),
}

/// The mission arguments with the clock flags as the `--set`s they stand for.
fn clocked(args: &MissionArgs, clock: &ClockArgs) -> MissionArgs {
    let sets = clock.sets();
    MissionArgs {
        file: args.file.clone(),
        set: args
            .set
            .iter()
            .cloned()
            .chain(sets.iter().map(|s| s.0.clone()))
            .collect(),
        flags: args.flags.iter().cloned().chain(sets).collect(),
    }
}

/// A role's (or a launcher's) failure: a clock the fleet does not run, or Zenoh options that
/// cannot work, is bad input; a signal before the work began an interrupt; anything else a
/// failed run.
fn role_failure(e: anyhow::Error) -> Failure {
    if e.downcast_ref::<tcpf_bus::clock::WrongClock>().is_some()
        || e.downcast_ref::<tcpf_bus::session::BadZenohConfig>().is_some()
        || e.downcast_ref::<tcpf_bus::typed::AlreadyRunning>().is_some()
    {
        Failure::Input(e)
    } else if e.downcast_ref::<tcpf_bus::signals::Interrupted>().is_some() {
        Failure::Interrupted(e)
    } else {
        Failure::Failed(e)
    }
}

fn load(args: &MissionArgs, seed: Option<u64>) -> Result<Mission, Failure> {
    let name = args.file.display().to_string();
    let cannot = |e: std::io::Error| Failure::Input(anyhow!("{name}: cannot read the mission file: {e}"));
    // Read no more than a mission may hold: an 80 MB file (valid, padded) took 3.8 GB to plan.
    let mut text = String::new();
    let limit = mission::MAX_FILE_BYTES;
    std::io::Read::read_to_string(
        &mut std::io::Read::take(std::fs::File::open(&args.file).map_err(cannot)?, limit + 1),
        &mut text,
    )
    .map_err(cannot)?;
    if text.len() as u64 > limit {
        return Err(Failure::Input(anyhow!(
            "{name}: a mission file is at most {} MiB; this one is longer",
            limit >> 20
        )));
    }
    let mut sets = args.set.clone();
    // `--seed` is one more `--set` that stands for a flag.
    let seed = seed.map(|seed| (format!("mission.seed={seed}"), format!("--seed {seed}")));
    sets.extend(seed.iter().map(|(set, _)| set.clone()));
    mission::parse(&name, &text, &sets).map_err(|mut e| {
        for (set, flag) in args.flags.iter().chain(&seed) {
            e.message = e.message.replace(&format!("--set {set}"), flag);
        }
        Failure::Input(e.into())
    })
}

/// A duration on the command line: seconds, finite, positive and at most a day.
fn seconds(text: &str) -> Result<Duration, String> {
    let s: f64 = text
        .parse()
        .map_err(|_| format!("`{text}` is not a number of seconds"))?;
    if s.is_finite() && s > 0.0 && s <= 86_400.0 {
        Ok(Duration::from_secs_f64(s))
    } else {
        Err(format!("{text} s: give a number of seconds in (0, 86400]"))
    }
}

/// The live view's address can be listened on: said before a run directory is made, which a
/// run that cannot serve would leave half-written.
fn live_free(live: Option<SocketAddr>) -> Result<(), Failure> {
    match live.map(std::net::TcpListener::bind) {
        Some(Err(e)) => Err(Failure::Input(anyhow!(
            "--live {}: cannot serve the live view there: {e}",
            live.expect("given")
        ))),
        _ => Ok(()),
    }
}

/// A run directory to create: a new or empty directory, so that a run never mixes its files
/// with another's.
fn fresh_out(out: Option<&Path>) -> Result<(), Failure> {
    let Some(out) = out.filter(|o| o.exists()) else {
        return Ok(());
    };
    let empty = out.is_dir() && std::fs::read_dir(out).is_ok_and(|mut d| d.next().is_none());
    if empty {
        Ok(())
    } else if out.is_dir() {
        Err(Failure::Input(anyhow!(
            "--out {}: the directory already holds files; give a new or empty one",
            out.display()
        )))
    } else {
        Err(Failure::Input(anyhow!(
            "--out {}: is a file, not a directory",
            out.display()
        )))
    }
}

/// Makes the run directory.
fn run_dir(out: Option<&Path>, mission: &Mission) -> Result<RunDir, Failure> {
    RunDir::create(out, mission).map_err(|e| out_failure(e, out.is_some()))
}

/// An output directory that cannot be made. One the user named (`given`) on a path that cannot
/// hold it (under a file or a directory that is not there or not theirs, a name too long) is
/// theirs to change, exit 2; a failing disk, or the default directory, is not.
fn out_failure(e: anyhow::Error, given: bool) -> Failure {
    use std::io::ErrorKind::*;
    let kind = e.root_cause().downcast_ref::<std::io::Error>().map(|io| io.kind());
    match kind {
        Some(NotFound | NotADirectory | PermissionDenied | ReadOnlyFilesystem | AlreadyExists | InvalidFilename)
            if given =>
        {
            Failure::Input(e.context("--out"))
        }
        _ => Failure::Failed(e),
    }
}

fn solve(mission: &Mission, file: &Path) -> Result<Plan, Failure> {
    planning::plan(mission).map_err(|e| Failure::Failed(anyhow!("{}: infeasible plan: {e}", file.display())))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let role = matches!(
        cli.command,
        Command::Planner { .. } | Command::World { .. } | Command::Agent { .. } | Command::Router { .. }
    );
    let filter =
        std::env::var("RUST_LOG").unwrap_or_else(|_| if role { "info,zenoh=warn" } else { "warn,zenoh=error" }.into());
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .init();
    let outcome = match cli.command {
        Command::Plan { mission, json } => plan(&mission, json),
        Command::Run {
            mission,
            clock,
            restart,
            out,
            in_process,
            seed,
            live,
            command_timeout,
            recorders,
            startup_timeout,
        } => run(
            &clocked(&mission, &clock),
            out.as_deref(),
            in_process,
            seed,
            (command_timeout, startup_timeout),
            launcher::Options {
                live,
                command_timeout: command_timeout.unwrap_or(launcher::COMMAND_TIMEOUT),
                startup_timeout: startup_timeout.unwrap_or(launcher::STARTUP),
                restart: restart == Restart::OnFailure,
                recorders,
            },
        ),
        Command::Bench { mission, count } => bench(&mission, count),
        Command::Report { dir } => report(&dir),
        Command::Gen {
            mission: Generated::Lanes { vehicles, loss },
        } => out(format_args!("{}", mission::generate::lanes(vehicles, loss))).map(|()| ExitCode::SUCCESS),
        Command::Sweep {
            mission,
            loss,
            param,
            seeds,
            processes,
            out,
        } => sweep(&mission, &loss, param.as_deref(), seeds, processes, out.as_deref()),
        Command::Pong { zenoh, count, id } => runtime()
            .and_then(|rt| rt.block_on(bench::pong(&zenoh, count, id)).map_err(role_failure))
            .map(|_| ExitCode::SUCCESS),
        Command::Planner { mission, zenoh, clock } => planner(&clocked(&mission, &clock), &zenoh),
        Command::Router { zenoh } => runtime()
            .and_then(|rt| rt.block_on(tcpf_coordinator::router::run(&zenoh)).map_err(role_failure))
            .map(|_| ExitCode::SUCCESS),
        Command::Record {
            mission,
            zenoh,
            clock,
            out,
            live,
            startup_timeout,
        } => record(
            &clocked(&mission, &clock),
            &zenoh,
            out.as_deref(),
            live,
            startup_timeout,
        ),
        Command::World {
            mission,
            zenoh,
            clock,
            vehicles,
            rejoin_timeout,
            recorders,
            startup_timeout,
            command_timeout,
        } => world(
            &clocked(&mission, &clock),
            &zenoh,
            tcpf_world::Options {
                startup_timeout,
                recorders,
                command_timeout,
                rejoin_timeout,
                vehicles,
            },
        ),
        Command::Agent {
            mission,
            zenoh,
            clock,
            id,
            startup_timeout,
            stale_timeout,
        } => agent(&clocked(&mission, &clock), &zenoh, id, startup_timeout, stale_timeout),
    };
    match outcome {
        Ok(code) => code,
        Err(Failure::Input(e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
        Err(Failure::Failed(e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
        Err(Failure::Interrupted(e)) => {
            eprintln!("{e:#}");
            ExitCode::from(130)
        }
    }
}

fn plan(args: &MissionArgs, json: bool) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    let plan = solve(&mission, &args.file)?;
    if json {
        sayln!(
            "{}",
            serde_json::to_string_pretty(&plan).map_err(|e| Failure::Failed(e.into()))?
        );
    } else {
        say!("{}", table::plan(&plan));
    }
    Ok(ExitCode::SUCCESS)
}

fn run(
    args: &MissionArgs,
    out: Option<&Path>,
    in_process: bool,
    seed: Option<u64>,
    (command_timeout, startup_timeout): (Option<Duration>, Option<Duration>),
    options: launcher::Options,
) -> Result<ExitCode, Failure> {
    let mission = load(args, seed)?;
    let realtime = mission.mission.clock == mission::ClockKind::Realtime;
    if in_process && realtime {
        return Err(Failure::Input(anyhow!(
            "--in-process runs lockstep only: the realtime clock is for fleets of processes"
        )));
    }
    if in_process && options.restart {
        return Err(Failure::Input(anyhow!(
            "--restart: an in-process run has no agent processes to start again"
        )));
    }
    if in_process && options.recorders > 0 {
        return Err(Failure::Input(anyhow!(
            "--recorders: an in-process run has no bus for other recorders to join"
        )));
    }
    for (flag, given) in [
        ("--command-timeout", command_timeout),
        ("--startup-timeout", startup_timeout),
    ] {
        if in_process && given.is_some() {
            return Err(Failure::Input(anyhow!(
                "{flag}: an in-process run has no processes to wait for"
            )));
        }
    }
    // The agents' default stale timeout: a neighbour waiting for a silent agent gives up on it
    // first, so that only the silent one is lost.
    if options.command_timeout <= Duration::from_secs(3) {
        return Err(Failure::Input(anyhow!(
            "--command-timeout {:?}: must exceed the agents' stale timeout (3 s), or an agent waiting for a silent neighbour would be lost with it",
            options.command_timeout
        )));
    }
    if !in_process && !realtime {
        launcher::launcher_runtime();
    }
    let plan = solve(&mission, &args.file)?;
    fresh_out(out)?;
    live_free(options.live)?;
    let dir = run_dir(out, &mission)?;
    let summary = if in_process {
        inprocess::run(&mission, &plan, &dir, options.live).map_err(Failure::Failed)?
    } else {
        let exe = std::env::current_exe().map_err(|e| Failure::Failed(e.into()))?;
        runtime()?
            .block_on(launcher::run(&mission, &plan, &dir, &exe, options))
            .map_err(role_failure)?
    };
    say!("{}", table::summary(&summary));
    sayln!("run directory: {}", dir.path.display());
    // A realtime run is not meant to be reproducible: it succeeds by arriving.
    Ok(code(
        summary.completed && (summary.reproducible || realtime),
        summary.interrupted,
    ))
}

fn runtime() -> Result<tokio::runtime::Runtime, Failure> {
    tokio::runtime::Runtime::new().map_err(|e| Failure::Failed(e.into()))
}

/// Runs a role on a runtime of its own, and leaves without waiting for the runtime's blocking
/// threads: Zenoh opens a session on one, which a signal cannot stop (it waits out its connect
/// timeout, a minute in configs/zenoh/).
fn role<F: std::future::Future>(work: F) -> Result<F::Output, Failure> {
    let rt = runtime()?;
    let out = rt.block_on(work);
    rt.shutdown_background();
    Ok(out)
}

fn code(ok: bool, interrupted: bool) -> ExitCode {
    match (ok, interrupted) {
        (_, true) => ExitCode::from(130),
        (true, _) => ExitCode::SUCCESS,
        _ => ExitCode::from(1),
    }
}

fn planner(args: &MissionArgs, zenoh: &ZenohArgs) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    let plan = solve(&mission, &args.file)?;
    let exit = role(planner_node::run(&mission, &plan, zenoh))?.map_err(role_failure)?;
    Ok(code(
        exit == planner_node::Exit::Ended,
        exit == planner_node::Exit::Interrupted,
    ))
}

fn world(args: &MissionArgs, zenoh: &ZenohArgs, options: tcpf_world::Options) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    if let Some(vehicles) = &options.vehicles {
        if mission.mission.clock != mission::ClockKind::Realtime {
            return Err(Failure::Input(anyhow!(
                "--vehicles: other processes can play vehicles only in realtime (--clock realtime); lockstep waits for every state"
            )));
        }
        if let Some(id) = vehicles
            .iter()
            .find(|&&id| !mission.vehicles.iter().any(|v| v.id == id))
        {
            return Err(Failure::Input(anyhow!(
                "--vehicles: {} has no vehicle with id {id}",
                args.file.display()
            )));
        }
    }
    let exit = role(tcpf_world::run(&mission, zenoh, &options))?.map_err(role_failure)?;
    Ok(code(
        matches!(exit, tcpf_world::Exit::Ended { lost: 0, short: 0, .. }),
        exit == tcpf_world::Exit::Interrupted,
    ))
}

fn agent(
    args: &MissionArgs,
    zenoh: &ZenohArgs,
    id: u32,
    startup_timeout: Duration,
    stale_timeout: Duration,
) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    if !mission.vehicles.iter().any(|v| v.id == id) {
        return Err(Failure::Input(anyhow!(
            "--id {id}: {} has no vehicle with that id",
            args.file.display()
        )));
    }
    let options = tcpf_agent::Options {
        startup_timeout,
        stale_timeout,
    };
    let exit = role(tcpf_agent::run(&mission, id, zenoh, &options))?.map_err(role_failure)?;
    Ok(code(
        exit == tcpf_agent::Exit::Ended,
        exit == tcpf_agent::Exit::Interrupted,
    ))
}

fn bench(args: &MissionArgs, count: u64) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    // Its figures are of lockstep ticks; a realtime fleet ticks with the wall clock.
    if mission.mission.clock != mission::ClockKind::Lockstep {
        return Err(Failure::Input(anyhow!(
            "{}: tcpf bench measures a lockstep fleet, and mission.clock is realtime (a realtime run takes the mission's own time)",
            args.file.display()
        )));
    }
    launcher::launcher_runtime();
    let seconds = |d: Duration| d.as_secs_f64();
    let started = Instant::now();
    let plan = solve(&mission, &args.file)?;
    let on_every_core = started.elapsed();
    let started = Instant::now();
    let _ = tcpf_core::planner::plan(&mission);
    let on_one = started.elapsed();
    sayln!(
        "plan ({} vehicles): {:.3} s on {} cores, {:.3} s on one (baseline): {:.2}x",
        plan.vehicles.len(),
        seconds(on_every_core),
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        seconds(on_one),
        seconds(on_one) / seconds(on_every_core)
    );

    let took = bench::in_process(&mission, &plan, 3);
    let rate = |d: Duration| took.steps as f64 / seconds(d) / 1e6;
    sayln!(
        "in-process: {:.2} M vehicle-steps/s; the world alone (baseline) {:.2} M/s: {:.2}x; \
         the world and the laws alone {:.2} M/s: {:.2}x",
        rate(took.fleet),
        rate(took.world),
        rate(took.fleet) / rate(took.world),
        rate(took.laws),
        rate(took.fleet) / rate(took.laws)
    );
    let [(_, kinematic), (_, medusa)] = bench::vehicle_models(&mission, &plan, 3);
    let per_second = |t: &bench::InProcess| t.steps as f64 / seconds(t.fleet) / 1e6;
    sayln!(
        "in-process on MEDUSA (every vehicle): {:.2} M vehicle-steps/s; kinematic (baseline) {:.2} M/s: {:.2}x",
        per_second(&medusa),
        per_second(&kinematic),
        per_second(&medusa) / per_second(&kinematic)
    );

    let exe = std::env::current_exe().map_err(|e| Failure::Failed(e.into()))?;
    // This process's own scratch directory: one a killed bench of the same pid left is stale.
    let scratch = std::env::temp_dir().join(format!("tcpf-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    let dir = RunDir::create(Some(&scratch), &mission).map_err(Failure::Failed)?;
    let rt = runtime()?;
    // Stopped by a signal, it measured nothing: its children go (dropped, they are killed), and
    // so does its scratch directory.
    let mut shutdown = rt.block_on(async { Shutdown::new() }).map_err(Failure::Failed)?;
    let interrupted = || {
        let _ = std::fs::remove_dir_all(&scratch);
        eprintln!("interrupted: no figures");
        Ok(code(false, true))
    };
    let median = |t: &[Duration]| t[t.len() / 2].as_secs_f64() * 1e6;
    let Some(direct) = rt.block_on(shutdown.unless(bench::ping(&exe, count, false))) else {
        return interrupted();
    };
    let Some(routed) = rt.block_on(shutdown.unless(bench::ping(&exe, count, true))) else {
        return interrupted();
    };
    let (direct, routed) = (direct.map_err(Failure::Failed)?, routed.map_err(Failure::Failed)?);
    let (summary, busiest) = rt
        .block_on(async {
            // The fleet's footprint, sampled while it runs: the largest seen.
            let sampling = tokio::spawn(async {
                let mut busiest = bench::Footprint::default();
                loop {
                    // Often enough to see a fleet of a second at least once.
                    tokio::time::sleep(Duration::from_millis(100)).await;
                    let now = tokio::task::spawn_blocking(|| bench::Footprint::of_children("agent"))
                        .await
                        .unwrap_or_default();
                    if now.pss_kib > busiest.pss_kib {
                        busiest = now;
                    }
                    if now.processes == 0 && busiest.processes > 0 {
                        return busiest;
                    }
                }
            });
            let summary = launcher::run(&mission, &plan, &dir, &exe, launcher::Options::default()).await;
            let busiest = tokio::time::timeout(Duration::from_secs(2), sampling).await;
            summary.map(|s| (s, busiest.ok().and_then(Result::ok).unwrap_or_default()))
        })
        .map_err(Failure::Failed)?;
    if summary.interrupted {
        return interrupted();
    }
    let Some(idle) = rt.block_on(shutdown.unless(bench::idle_fleet(&exe, plan.vehicles.len()))) else {
        return interrupted();
    };
    let idle = idle.map_err(Failure::Failed)?;
    let _ = std::fs::remove_dir_all(&dir.path);
    let tick = summary.tick_wall_time_us;
    sayln!(
        "zenoh round trip between two processes: median {:.1} µs direct, {:.1} µs through a router",
        median(&direct),
        median(&routed)
    );
    sayln!(
        "lockstep tick ({} vehicles, {} ticks): {:.1} µs; tick / round trip: {:.2} direct, {:.2} through a router",
        plan.vehicles.len(),
        summary.results.ticks,
        tick,
        tick / median(&direct),
        tick / median(&routed)
    );
    // A short mission's wall time is much its start: the tick says how fast the fleet runs.
    sayln!(
        "simulated / wall time: {:.1} by the tick, {:.1} from the start to the end",
        mission.mission.control_period / (tick * 1e-6),
        summary.speedup()
    );
    let (rss, pss) = busiest.per_process_mib();
    let (idle_rss, idle_pss) = idle.per_process_mib();
    sayln!(
        "per agent: RSS {rss:.1} MiB, PSS {pss:.1} MiB; an idle Zenoh client (baseline): RSS {idle_rss:.1} MiB, PSS {idle_pss:.1} MiB"
    );
    sayln!(
        "agents' sockets: {} for {} agents; idle clients' (baseline): {}",
        busiest.sockets,
        busiest.processes,
        idle.sockets
    );
    Ok(ExitCode::SUCCESS)
}

fn report(dir: &Path) -> Result<ExitCode, Failure> {
    // A sweep's directory holds its runs' directories when it ran them as processes.
    if dir.join("sweep.csv").is_file() && !dir.join("summary.json").exists() {
        return Err(Failure::Input(anyhow!(
            "{}: a sweep's directory (sweep.csv), which tcpf sweep wrote with its sweep.html; tcpf report reads one run's directory",
            dir.display()
        )));
    }
    if !dir.join("summary.json").is_file() {
        return Err(Failure::Input(anyhow!(
            "{}: no summary.json: not a run directory, or a run stopped before it wrote one (killed outright, say)",
            dir.display()
        )));
    }
    // What it cannot read or make sense of is the directory's fault: bad input.
    tcpf_report::report::write(dir).map_err(Failure::Input)?;
    sayln!("{}", dir.join("report.html").display());
    Ok(ExitCode::SUCCESS)
}

fn sweep(
    args: &MissionArgs,
    loss: &[String],
    param: Option<&str>,
    seeds: u64,
    processes: bool,
    out: Option<&Path>,
) -> Result<ExitCode, Failure> {
    let (key, column, values): (String, String, Vec<String>) = match param {
        Some(p) => {
            let (k, v) = p
                .split_once('=')
                .ok_or_else(|| Failure::Input(anyhow!("--param {p}: expected KEY=V1,V2,...")))?;
            (
                k.trim().into(),
                k.trim().into(),
                v.split(',').map(|s| s.trim().to_string()).collect(),
            )
        }
        None => (
            "comms.loss".into(),
            "loss".into(),
            loss.iter().map(|s| s.trim().to_string()).collect(),
        ),
    };
    if values.iter().any(|v| v.is_empty()) {
        return Err(Failure::Input(anyhow!("{key}: an empty value in {}", values.join(","))));
    }
    // The `--set` that names `k`, if one does.
    let set_of = |k: &str| {
        args.set
            .iter()
            .find(|s| s.split_once('=').is_some_and(|(set, _)| set.trim() == k))
    };
    if key == "mission.seed" || set_of("mission.seed").is_some() {
        return Err(Failure::Input(anyhow!(
            "mission.seed: the sweep gives each run its seed (--seeds N: 1 to N); sweep or set another key"
        )));
    }
    // Runs are counted, and written in sweep.json, as integers JSON keeps exact.
    if (values.len() as u64)
        .checked_mul(seeds)
        .is_none_or(|runs| runs > 1 << 53)
    {
        return Err(Failure::Input(anyhow!(
            "--seeds {seeds}: {} values × {seeds} seeds are more runs than a sweep counts (2^53)",
            values.len()
        )));
    }
    if let Some(set) = set_of(&key) {
        return Err(Failure::Input(anyhow!(
            "--set {set}: {key} is the key the sweep sets, value by value"
        )));
    }
    if let Some(v) = values.iter().find(|v| v.starts_with('[') || v.ends_with(']')) {
        return Err(Failure::Input(anyhow!(
            "{key}: {v} is part of an array, and an array cannot be swept: the values are split at commas"
        )));
    }
    // "0" and "0.0" are one number: the same runs twice.
    let same = |a: &str, b: &str| a == b || matches!((a.parse::<f64>(), b.parse::<f64>()), (Ok(x), Ok(y)) if x == y);
    if let Some((v, w)) = values
        .iter()
        .enumerate()
        .find_map(|(i, v)| values[..i].iter().find(|w| same(v, w)).map(|w| (v, w)))
    {
        return Err(Failure::Input(anyhow!(
            "{key}: the value {v} is swept twice ({w} and {v})"
        )));
    }
    fresh_out(out)?;
    let mut grid = sweep::Grid {
        values: Vec::with_capacity(values.len()),
        seeds,
    };
    for value in &values {
        let mut one = MissionArgs {
            file: args.file.clone(),
            set: args.set.clone(),
            flags: args.flags.clone(),
        };
        one.set.push(format!("{key}={value}"));
        // An error in a swept value names the sweep's flag, not a --set the user never wrote.
        let flag = match param {
            Some(p) => format!("--param {} (the value {value})", p.trim()),
            None => format!("--loss {value}"),
        };
        one.flags.push((format!("{key}={value}"), flag));
        let mission = load(&one, None)?;
        if !processes && mission.mission.clock == mission::ClockKind::Realtime {
            return Err(Failure::Input(anyhow!(
                "an in-process sweep runs lockstep only: the realtime clock is for fleets of processes (--processes)"
            )));
        }
        grid.values.push((value.clone(), mission));
    }
    // Every value planned before anything is written: an infeasible one leaves no directory.
    let plans = grid.plans().map_err(Failure::Failed)?;
    // The file alone may be incomplete (a table set key by key, the swept key among them).
    let base = &grid.values[0].1;
    let (out, mut rows) = tcpf_report::sweep::Sweep::create(out, base, &column, &values).map_err(|e| {
        let given = out.is_some();
        let e = match out {
            Some(out) => e.context(format!("{}: cannot write the sweep there", out.display())),
            None => e,
        };
        out_failure(e, given)
    })?;
    let interrupted = if processes {
        let exe = std::env::current_exe().map_err(|e| Failure::Failed(e.into()))?;
        runtime()?
            .block_on(sweep::run_processes(&grid, &plans, &out, &exe, &mut rows))
            .map_err(Failure::Failed)?
    } else {
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        sweep::run_in_process(&grid, &plans, threads, &mut rows).map_err(Failure::Failed)?
    };
    let mode = if processes { "processes" } else { "in-process" };
    let summary = rows.summary(&base.mission.name, &key, seeds, mode);
    let table = tcpf_report::sweep::write(&out, &summary).map_err(Failure::Failed)?;
    say!("{table}");
    sayln!("sweep directory: {}", out.display());
    Ok(code(summary.failed_runs.is_empty(), interrupted))
}

fn record(
    args: &MissionArgs,
    zenoh: &ZenohArgs,
    out: Option<&Path>,
    live: Option<SocketAddr>,
    startup_timeout: Duration,
) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    let plan = solve(&mission, &args.file)?;
    fresh_out(out)?;
    live_free(live)?;
    // Bad Zenoh options are bad input before the run directory is made, which they would
    // leave behind half written.
    zenoh.config().map_err(role_failure)?;
    let dir = run_dir(out, &mission)?;
    let summary = role(tcpf_coordinator::recording::record(
        &mission,
        &plan,
        &dir,
        zenoh,
        live,
        startup_timeout,
    ))?
    .map_err(|e| {
        // Nothing recorded (no session, no world, refused by the world's clock): the
        // corrected command may take the same --out.
        if e.downcast_ref::<tcpf_coordinator::recording::NothingRecorded>()
            .is_some()
        {
            dir.discard();
        }
        role_failure(e)
    })?;
    say!("{}", table::summary(&summary));
    sayln!("run directory: {}", dir.path.display());
    let realtime = mission.mission.clock == mission::ClockKind::Realtime;
    Ok(code(
        summary.completed && (summary.reproducible || realtime),
        summary.interrupted,
    ))
}
