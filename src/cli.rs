//! The command line: every subcommand, each an `Args` struct beside the `run` that does it (the
//! arguments several share, and how a value is read from it, are `args`).

use std::process::ExitCode;

use clap::{Parser, Subcommand};
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
