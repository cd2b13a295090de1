//! `tcpf run`, `plan` and `report`: a mission's plan, its run, and a run's report.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::anyhow;
use clap::{Args, ValueEnum};
use tcpf_bus::waits::{self, Timeouts};
use tcpf_coordinator::{inprocess, launcher};
use tcpf_core::mission;
use tcpf_report::provenance::Invocation;
use tcpf_report::table;

use crate::args::{command_timeout, figure_width, more_recorders, ros2_domain, seconds, ClockArgs, MissionArgs};
use crate::failure::{code, role_failure, Failure};
use crate::missions::{load, solve};
use crate::outputs::{fresh_out, live_free, ros2_open_free, run_dir};
use crate::runtime::runtime;

#[derive(Args)]
pub struct RunArgs {
    #[command(flatten)]
    mission: MissionArgs,
    #[command(flatten)]
    clock: ClockArgs,
    /// Start a dead agent again (it rejoins the run), or never (its vehicle is lost).
    #[arg(long, value_enum, default_value = "never", conflicts_with = "in_process")]
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
    /// More than the agents' stale timeout.
    #[arg(long, default_value = waits::COMMAND_S, value_parser = command_timeout, allow_hyphen_values = true, conflicts_with = "in_process")]
    command_timeout: Duration,
    /// Speak ROS 2 (rmw_zenoh) on this domain beside tcpf's own protocol, over the mission's
    /// [ros2] domain: the world and every agent as ROS 2 nodes (docs/ROS2.md).
    #[arg(long, value_name = "DOMAIN", num_args = 0..=1, default_missing_value = "0", value_parser = ros2_domain(), conflicts_with = "in_process")]
    ros2: Option<u32>,
    /// With ROS 2, the world also listens here with no credential (by default where
    /// rmw_zenohd would, tcp/127.0.0.1:7447): a stock ROS 2 node on this machine joins with
    /// no configuration at all, and may only listen. For a network only you use.
    #[arg(long, value_name = "ENDPOINT", num_args = 0..=1, default_missing_value = "tcp/127.0.0.1:7447", conflicts_with = "in_process")]
    ros2_open: Option<String>,
    /// Start the run only once N more recorders have joined: `tcpf record` or tools of your
    /// own, with the run directory's `zenoh.json5` (-c).
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = more_recorders(), conflicts_with = "in_process")]
    recorders: usize,
    /// Seconds the world waits for every agent and recorder before it gives up and says who
    /// is missing.
    #[arg(long, default_value = waits::STARTUP_S, value_parser = seconds, allow_hyphen_values = true, conflicts_with = "in_process")]
    startup_timeout: Duration,
    /// How each role proves to the world which it is: its own certificate (mutual TLS), or
    /// its own user and password over TCP, for tools whose Zenoh has no TLS.
    #[arg(long, value_enum, default_value = "certificates", conflicts_with = "in_process")]
    links: launcher::Links,
}

/// What `tcpf run` does when an agent dies.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Restart {
    /// Its vehicle is lost and drifts.
    Never,
    /// The agent is started again and rejoins.
    OnFailure,
}

#[derive(Args)]
pub struct PlanArgs {
    #[command(flatten)]
    mission: MissionArgs,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct ReportArgs {
    /// The run directory.
    dir: PathBuf,
    /// The figures' printed width (figures/*.pdf, *.svg): column (3.5 in), double (7.16 in)
    /// or inches; every text is at least 8 pt at it.
    #[arg(long, value_name = "WIDTH", default_value = "column", value_parser = figure_width)]
    figure_width: f64,
}

impl PlanArgs {
    pub fn run(self) -> Result<ExitCode, Failure> {
        plan(&self.mission, self.json)
    }
}

impl RunArgs {
    pub fn run(self, invocation: Invocation) -> Result<ExitCode, Failure> {
        let options = launcher::Options {
            live: self.live,
            roles: Timeouts {
                command: self.command_timeout,
                startup: self.startup_timeout,
                ..Timeouts::default()
            },
            restart: self.restart == Restart::OnFailure,
            recorders: self.recorders,
            ros2: self.ros2,
            ros2_open: self.ros2_open,
            links: self.links,
            ..launcher::Options::default()
        };
        let mission = self.mission.clocked(&self.clock);
        run(
            &mission,
            self.out.as_deref(),
            self.in_process,
            self.seed,
            options,
            invocation,
        )
    }
}

impl ReportArgs {
    pub fn run(self) -> Result<ExitCode, Failure> {
        report(&self.dir, self.figure_width)
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
        for line in tcpf_core::links::modem::link_budget(&mission).into_iter().flatten() {
            sayln!("{line}");
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn run(
    args: &MissionArgs,
    out: Option<&Path>,
    in_process: bool,
    seed: Option<u64>,
    options: launcher::Options,
    invocation: Invocation,
) -> Result<ExitCode, Failure> {
    let mission = load(args, seed)?;
    let realtime = mission.mission.clock == mission::ClockKind::Realtime;
    // The clock may come from the mission file: clap cannot see it.
    if in_process && realtime {
        return Err(Failure::Input(anyhow!(
            "--in-process runs lockstep only: the realtime clock is for fleets of processes"
        )));
    }
    if !in_process && !realtime {
        launcher::launcher_runtime();
    }
    // It records the run, and the roles it starts inherit what it got.
    if realtime {
        tcpf_bus::priority::for_realtime("tcpf run");
    }
    if in_process && mission.ros2.is_some() {
        eprintln!(
            "{}: its [ros2] is for a fleet of processes; this run is in-process and speaks no ROS 2",
            args.file.display()
        );
    }
    let plan = solve(&mission, &args.file)?;
    fresh_out(out)?;
    live_free(options.live)?;
    if !in_process {
        ros2_open_free(
            options.ros2_open.as_deref(),
            mission.ros2(options.ros2).is_some(),
            options.links,
        )?;
    }
    let dir = run_dir(out, &mission, invocation)?;
    let summary = if in_process {
        inprocess::run(&mission, &plan, &dir, options.live).map_err(Failure::failed)?
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

fn report(dir: &Path, figure_width: f64) -> Result<ExitCode, Failure> {
    // A sweep's directory holds its runs' directories when it ran them as processes.
    if dir.join("runs.csv").is_file() && !dir.join("summary.json").exists() {
        return Err(Failure::Input(anyhow!(
            "{}: a sweep's directory (runs.csv), which tcpf sweep wrote with its sweep.html; tcpf report reads one run's directory",
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
    tcpf_report::report::write(dir, &tcpf_report::report::Options { figure_width }).map_err(Failure::input)?;
    sayln!("{}", dir.join("report.html").display());
    Ok(ExitCode::SUCCESS)
}
