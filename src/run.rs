//! `tcpf run`, `plan` and `report`: a mission's plan, its run, and a run's report.

use std::path::Path;
use std::process::ExitCode;

use anyhow::anyhow;
use tcpf_coordinator::{inprocess, launcher};
use tcpf_core::mission;
use tcpf_report::table;

use crate::cli::MissionArgs;
use crate::outputs::{fresh_out, live_free, ros2_open_free, run_dir};
use crate::{code, load, role_failure, runtime, solve, Failure};

pub fn plan(args: &MissionArgs, json: bool) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    let plan = solve(&mission, &args.file)?;
    if json {
        sayln!(
            "{}",
            serde_json::to_string_pretty(&plan).map_err(|e| Failure::Failed(e.into()))?
        );
    } else {
        say!("{}", table::plan(&plan));
        for line in tcpf_core::modem::link_budget(&mission).into_iter().flatten() {
            sayln!("{line}");
        }
    }
    Ok(ExitCode::SUCCESS)
}

pub fn run(
    args: &MissionArgs,
    out: Option<&Path>,
    in_process: bool,
    seed: Option<u64>,
    options: launcher::Options,
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

pub fn report(dir: &Path, figure_width: f64) -> Result<ExitCode, Failure> {
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
    tcpf_report::report::write(dir, &tcpf_report::report::Options { figure_width }).map_err(Failure::Input)?;
    sayln!("{}", dir.join("report.html").display());
    Ok(ExitCode::SUCCESS)
}
