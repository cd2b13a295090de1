//! The command line: every subcommand, each an `Args` struct beside the `run` that does it, the
//! arguments several share, and how a value is read from it.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, Parser, Subcommand, ValueEnum};
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::waits::Timeouts;
use tcpf_core::mission;
use tcpf_report::provenance::Invocation;

use crate::failure::Failure;
use crate::{bench, missions, roles, run, sweep};

#[derive(Parser)]
#[command(
    name = "tcpf",
    version,
    about = "Time-coordinated path following for fleets of vehicles"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Launch a mission, record it and write the run directory.
    Run(run::RunArgs),
    /// Solve the trajectory generation problem and print the plan.
    Plan(run::PlanArgs),
    /// Fault-injection experiment: every (grid point, seed) pair, summarised per grid point.
    #[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
    Sweep(sweep::SweepCommandArgs),
    /// Print a generated mission file, for fleets of any size.
    Gen(missions::GenArgs),
    /// Write (again) a run directory's report.html from its recorded files.
    Report(run::ReportArgs),
    /// Every speed figure beside its baseline: the plan, the in-process fleet, the lockstep tick
    /// against a raw Zenoh round trip, the agents' memory and sockets.
    Bench(bench::BenchArgs),
    /// The echo side of `tcpf bench`.
    #[command(hide = true)]
    Pong(bench::PongArgs),
    /// Make a fleet's credentials for roles started by hand: with a mission, a directory of one
    /// certificate per role and the router's, with its access rules; without, one user and
    /// password that every role and the router share.
    Credential(roles::CredentialArgs),
    /// A Zenoh router for a testbed: every role connects to it (configs/zenoh/).
    Router(roles::RouterArgs),
    /// Role: plan and serve every vehicle's path.
    Planner(roles::PlannerArgs),
    /// Role: the world, which integrates the vehicles and keeps the fleet's clock.
    World(roles::WorldArgs),
    /// Role: record a fleet started by hand (start its world with --recorders 1).
    Record(roles::RecordArgs),
    /// Role: the agent of one vehicle.
    Agent(roles::AgentArgs),
}

impl Command {
    /// A role of a fleet (or its router), which logs what it does, rather than a command.
    pub fn is_role(&self) -> bool {
        matches!(
            self,
            Command::Planner(_) | Command::World(_) | Command::Agent(_) | Command::Record(_) | Command::Router(_)
        )
    }

    /// Carries the command out; `invocation` is how this process was started, which whatever it
    /// writes names as its provenance.
    pub fn run(self, invocation: Invocation) -> Result<ExitCode, Failure> {
        match self {
            Command::Run(args) => args.run(invocation),
            Command::Plan(args) => args.run(),
            Command::Sweep(args) => args.run(invocation),
            Command::Gen(args) => args.run(),
            Command::Report(args) => args.run(),
            Command::Bench(args) => args.run(),
            Command::Pong(args) => args.run(),
            Command::Credential(args) => args.run(),
            Command::Router(args) => args.run(),
            Command::Planner(args) => args.run(),
            Command::World(args) => args.run(),
            Command::Record(args) => args.run(invocation),
            Command::Agent(args) => args.run(),
        }
    }
}

#[derive(Args)]
pub struct MissionArgs {
    /// Mission file (TOML).
    pub file: PathBuf,
    /// Override a mission key: `section.key=value`, `section.table.key=value`, or
    /// `vehicle.<id>.key=value`.
    #[arg(long = "set", value_name = "K=V")]
    pub set: Vec<String>,
    /// The `set`s that stand for other flags, and those flags as typed: what an error names.
    #[arg(skip)]
    pub flags: Vec<(String, String)>,
}

/// The clock a fleet runs on.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Clock {
    /// The world waits for every command: reproducible.
    Lockstep,
    /// The wall clock.
    Realtime,
}

impl Clock {
    fn as_str(self) -> &'static str {
        match self {
            Clock::Lockstep => "lockstep",
            Clock::Realtime => "realtime",
        }
    }
}

/// Which clock the fleet runs on; on top of the mission's `[mission] clock` and `time_scale`.
#[derive(Args, Clone)]
pub struct ClockArgs {
    /// The clock the fleet runs on.
    #[arg(long, value_enum)]
    pub clock: Option<Clock>,
    /// Realtime: simulated seconds per wall second (1: real time).
    #[arg(long, value_name = "X", value_parser = time_scale, allow_hyphen_values = true)]
    pub time_scale: Option<f64>,
}

impl ClockArgs {
    /// The mission keys these flags stand for, each with its flag. `--clock lockstep` alone
    /// also sets the time scale back to 1, which only the realtime clock may change.
    pub fn sets(&self) -> Vec<(String, String)> {
        let mut sets = Vec::new();
        if let Some(c) = self.clock.map(Clock::as_str) {
            sets.push((format!("mission.clock={c}"), format!("--clock {c}")));
            if self.clock == Some(Clock::Lockstep) && self.time_scale.is_none() {
                sets.push(("mission.time_scale=1.0".into(), format!("--clock {c}")));
            }
        }
        if let Some(x) = self.time_scale {
            sets.push((format!("mission.time_scale={x:?}"), format!("--time-scale {x}")));
        }
        sets
    }
}

/// What every role started by hand takes: its mission, the Zenoh options of its session, and
/// the clock (the planner too, whose paths do not depend on it, so that one command line serves
/// every role).
#[derive(Args)]
pub struct RoleArgs {
    #[command(flatten)]
    pub mission: MissionArgs,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    #[command(flatten)]
    pub clock: ClockArgs,
}

impl RoleArgs {
    /// The mission, with the clock flags as the `--set`s they stand for.
    pub fn mission(&self) -> MissionArgs {
        missions::clocked(&self.mission, &self.clock)
    }
}

/// The band around a mean over seeds.
#[derive(Clone, Copy, ValueEnum)]
pub enum Band {
    /// Its 95 % confidence interval.
    Ci95,
    /// The least and the greatest of the seeds.
    MinMax,
}

/// How a sweep's figures are drawn: `--band` and `--figure-width`. (Flags of `SweepArgs` and
/// of `sweep merge` themselves: clap takes an optional flattened struct as absent when it holds
/// another.)
pub fn look(band: Band, figure_width: f64) -> tcpf_report::sweep::figures::Look {
    use tcpf_report::sweep::figures;
    figures::Look {
        band: match band {
            Band::Ci95 => figures::Band::Ci95,
            Band::MinMax => figures::Band::MinMax,
        },
        width: figure_width,
    }
}

pub fn figure_width(text: &str) -> Result<f64, String> {
    use tcpf_report::style::{COLUMN, DOUBLE_COLUMN};
    match text {
        "column" => Ok(COLUMN),
        "double" => Ok(DOUBLE_COLUMN),
        _ => match text.strip_suffix("in").unwrap_or(text).trim().parse::<f64>() {
            Ok(w) if (2.0..=20.0).contains(&w) => Ok(w),
            _ => Err(format!(
                "{text}: give column (3.5 in), double (7.16 in) or a width in inches from 2 to 20"
            )),
        },
    }
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

pub fn recorders() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new().range(0..=MAX_RECORDERS)
}

/// `tcpf run --recorders`: the recorders beside the launcher's own, which its world counts too.
pub fn more_recorders() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new().range(0..=MAX_RECORDERS - 1)
}

/// A ROS 2 domain id: ROS 2 allows 0 to 232.
pub fn ros2_domain() -> clap::builder::RangedU64ValueParser<u32> {
    clap::builder::RangedU64ValueParser::<u32>::new().range(0..=232)
}

/// A probability on the command line: a number in [0, 1].
pub fn probability(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(p) if (0.0..=1.0).contains(&p) => Ok(p),
        _ => Err(format!("{text}: give a probability in [0, 1]")),
    }
}

/// A duration on the command line: seconds, finite, positive and at most a day.
pub fn seconds(text: &str) -> Result<Duration, String> {
    let s: f64 = text
        .parse()
        .map_err(|_| format!("`{text}` is not a number of seconds"))?;
    if s.is_finite() && s > 0.0 && s <= 86_400.0 {
        Ok(Duration::from_secs_f64(s))
    } else {
        Err(format!("{text} s: give a number of seconds in (0, 86400]"))
    }
}

/// `tcpf run --command-timeout`: more than the agents' stale timeout, or an agent waiting for a
/// silent neighbour would be lost with it.
pub fn command_timeout(text: &str) -> Result<Duration, String> {
    let stale = Timeouts::default().stale;
    match seconds(text)? {
        d if d <= stale => Err(format!(
            "{text} s: must exceed the agents' stale timeout ({} s), or an agent waiting for a silent neighbour would be lost with it",
            stale.as_secs()
        )),
        d => Ok(d),
    }
}
