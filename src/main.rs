//! `tcpf`: time-coordinated path following for fleets of vehicles. One binary, every role.

use std::io::IsTerminal;
use std::path::Path;
use std::process::ExitCode;

use anyhow::anyhow;
use clap::Parser;
use tcpf_bus::credential::Proof;
use tcpf_coordinator::{launcher, planning};
use tcpf_core::mission::{self, Mission};
use tcpf_core::planner::Plan;

use cli::{Cli, ClockArgs, Command, Generated, MissionArgs, Restart};

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
    ($($arg:tt)*) => { $crate::out(format_args!($($arg)*))? };
}

/// `println!` through `out`.
macro_rules! sayln {
    ($($arg:tt)*) => { $crate::out(format_args!("{}\n", format_args!($($arg)*)))? };
}

mod bench;
mod cli;
mod outputs;
mod roles;
mod run;
mod sweep;

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
        || e.downcast_ref::<tcpf_bus::claim::AlreadyRunning>().is_some()
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
    // Each as the user gave it: a --set, or a flag that stands for one (--clock, --seed).
    let flag = |set: &String| args.flags.iter().find(|(s, _)| s == set).map(|(_, said)| said.clone());
    let mut overrides: Vec<mission::Override> = args
        .set
        .iter()
        .map(|set| mission::Override {
            said: flag(set).unwrap_or_else(|| format!("--set {set}")),
            set: set.clone(),
        })
        .collect();
    overrides.extend(seed.map(|seed| mission::Override {
        set: format!("mission.seed={seed}"),
        said: format!("--seed {seed}"),
    }));
    mission::parse_with(&name, &text, &overrides).map_err(|e| Failure::Input(e.into()))
}

fn solve(mission: &Mission, file: &Path) -> Result<Plan, Failure> {
    planning::plan(mission).map_err(|e| Failure::Failed(anyhow!("{}: infeasible plan: {e}", file.display())))
}

fn main() -> ExitCode {
    tcpf_report::rundir::Invocation {
        command: std::env::args().collect(),
        version: env!("CARGO_PKG_VERSION").into(),
        commit: option_env!("TCPF_COMMIT").filter(|c| !c.is_empty()).map(String::from),
    }
    .set();
    let cli = Cli::parse();
    let role = matches!(
        cli.command,
        Command::Planner { .. }
            | Command::World { .. }
            | Command::Agent { .. }
            | Command::Record { .. }
            | Command::Router { .. }
    );
    let filter =
        std::env::var("RUST_LOG").unwrap_or_else(|_| if role { "info,zenoh=warn" } else { "warn,zenoh=error" }.into());
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .init();
    let outcome = match cli.command {
        Command::Plan { mission, json } => run::plan(&mission, json),
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
            ros2,
            ros2_open,
            links,
        } => run::run(
            &clocked(&mission, &clock),
            out.as_deref(),
            in_process,
            seed,
            launcher::Options {
                live,
                command_timeout,
                startup_timeout,
                restart: restart == Restart::OnFailure,
                recorders,
                ros2,
                ros2_open,
                links,
                ..launcher::Options::default()
            },
        ),
        Command::Bench { mission, count, fleets } => bench::run(&mission, count, &fleets),
        Command::Report { dir, figure_width } => run::report(&dir, figure_width),
        Command::Gen {
            mission: Generated::Lanes { vehicles, loss },
        } => out(format_args!("{}", mission::generate::lanes(vehicles, loss))).map(|()| ExitCode::SUCCESS),
        Command::Sweep {
            merge:
                Some(cli::SweepCommand::Merge {
                    dirs,
                    out,
                    band,
                    figure_width,
                }),
            ..
        } => sweep::merge(&dirs, &out, cli::look(&band, figure_width)),
        Command::Sweep {
            sweep: Some(args), ..
        } => sweep::run(&args),
        Command::Sweep { .. } => Err(Failure::Input(anyhow::anyhow!(
            "tcpf sweep: give a mission file and what to sweep (tcpf sweep FILE --loss ... --seeds N), or `tcpf sweep merge DIR... --out DIR`"
        ))),
        Command::Pong { zenoh, count, id } => runtime()
            .and_then(|rt| {
                rt.block_on(tcpf_coordinator::bench::pong(&zenoh, count, id))
                    .map_err(role_failure)
            })
            .map(|_| ExitCode::SUCCESS),
        Command::Planner { role } => roles::planner(&clocked(&role.mission, &role.clock), &role.zenoh),
        Command::Credential {
            path,
            mission: None,
            ..
        } => roles::credential(&path),
        Command::Credential {
            path,
            mission: Some(file),
            set,
            ros2,
            played,
            hosts,
            passwords,
        } => roles::fleet_credentials(
            &path,
            &MissionArgs {
                file,
                set,
                flags: Vec::new(),
            },
            ros2,
            &played,
            match passwords {
                true => Proof::Passwords,
                false => Proof::Certificates { hosts: &hosts },
            },
        ),
        Command::Router { zenoh } => {
            // Every message of a fleet on a router passes through it: a realtime role is late
            // when its router is.
            tcpf_bus::priority::for_realtime("router");
            runtime()
                .and_then(|rt| rt.block_on(tcpf_coordinator::router::run(&zenoh)).map_err(role_failure))
                .map(|_| ExitCode::SUCCESS)
        }
        Command::Record {
            role,
            out,
            live,
            startup_timeout,
            ros2,
        } => roles::record(
            &clocked(&role.mission, &role.clock),
            &role.zenoh,
            out.as_deref(),
            live,
            startup_timeout,
            ros2,
        ),
        Command::World {
            role,
            vehicles,
            rejoin_timeout,
            recorders,
            startup_timeout,
            command_timeout,
            ros2,
            no_rivals,
        } => roles::world(
            &clocked(&role.mission, &role.clock),
            &role.zenoh,
            tcpf_world::Options {
                startup_timeout,
                recorders,
                command_timeout,
                rejoin_timeout,
                vehicles,
                ros2,
                rivals: rivals(no_rivals, &role.zenoh),
            },
        ),
        Command::Agent {
            role,
            id,
            startup_timeout,
            stale_timeout,
            ros2,
            no_rivals,
        } => roles::agent(
            &clocked(&role.mission, &role.clock),
            &role.zenoh,
            id,
            tcpf_agent::Options {
                startup_timeout,
                stale_timeout,
                ros2,
                rivals: rivals(no_rivals, &role.zenoh),
            },
        ),
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

fn rivals(none: bool, zenoh: &tcpf_bus::session::ZenohArgs) -> tcpf_bus::claim::Rivals {
    use tcpf_bus::claim::Rivals;
    match (none, zenoh.is_client()) {
        (true, _) => Rivals::None,
        (false, true) => Rivals::OneRouter,
        (false, false) => Rivals::Possible,
    }
}

fn code(ok: bool, interrupted: bool) -> ExitCode {
    match (ok, interrupted) {
        (_, true) => ExitCode::from(130),
        (true, _) => ExitCode::SUCCESS,
        _ => ExitCode::from(1),
    }
}
