//! `tcpf`: time-coordinated path following for fleets of vehicles. One binary, every role.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::anyhow;
use clap::{Args, Parser, Subcommand};
use tcpf_coordinator::{inprocess, rundir::RunDir, table};
use tcpf_core::mission::{self, Mission};
use tcpf_core::planner::{self, Plan};

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
    /// Override a mission key: `section.key=value`, or `vehicle.<id>.key=value`.
    #[arg(long = "set", value_name = "K=V")]
    set: Vec<String>,
}

#[derive(Subcommand)]
enum Command {
    /// Launch a mission, record it and write the run directory.
    Run {
        #[command(flatten)]
        mission: MissionArgs,
        /// Run directory (default runs/<mission>-<timestamp>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Drive every machine in one loop instead of one process per role.
        #[arg(long)]
        in_process: bool,
        /// Mission seed (overrides mission.seed).
        #[arg(long)]
        seed: Option<u64>,
    },
    /// Solve the trajectory generation problem and print the plan.
    Plan {
        #[command(flatten)]
        mission: MissionArgs,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
    },
}

/// How a command failed: exit code 2 for bad input, 1 for a mission or run that failed.
enum Failure {
    Input(anyhow::Error),
    Failed(anyhow::Error),
}

fn load(args: &MissionArgs, seed: Option<u64>) -> Result<Mission, Failure> {
    let name = args.file.display().to_string();
    let text = std::fs::read_to_string(&args.file)
        .map_err(|e| Failure::Input(anyhow!("{name}: cannot read the mission file: {e}")))?;
    let mut sets = args.set.clone();
    if let Some(seed) = seed {
        sets.push(format!("mission.seed={seed}"));
    }
    mission::parse(&name, &text, &sets).map_err(|e| Failure::Input(e.into()))
}

fn solve(mission: &Mission, file: &Path) -> Result<Plan, Failure> {
    planner::plan(mission).map_err(|e| Failure::Failed(anyhow!("{}: infeasible plan: {e}", file.display())))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = match cli.command {
        Command::Plan { mission, json } => plan(&mission, json),
        Command::Run {
            mission,
            out,
            in_process,
            seed,
        } => run(&mission, out.as_deref(), in_process, seed),
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
    }
}

fn plan(args: &MissionArgs, json: bool) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    let plan = solve(&mission, &args.file)?;
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&plan).map_err(|e| Failure::Failed(e.into()))?
        );
    } else {
        print!("{}", table::plan(&plan));
    }
    Ok(ExitCode::SUCCESS)
}

fn run(args: &MissionArgs, out: Option<&Path>, in_process: bool, seed: Option<u64>) -> Result<ExitCode, Failure> {
    let mission = load(args, seed)?;
    let plan = solve(&mission, &args.file)?;
    if !in_process {
        return Err(Failure::Input(anyhow!(
            "running as processes is not built yet: add --in-process"
        )));
    }
    let dir = RunDir::create(out, &mission).map_err(Failure::Failed)?;
    let summary = inprocess::run(&mission, &plan, &dir).map_err(Failure::Failed)?;
    print!("{}", table::summary(&summary));
    println!("run directory: {}", dir.path.display());
    Ok(if summary.completed {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
