//! `tcpf bench`: every speed figure beside a baseline measured in the same run
//! (`tcpf_coordinator::bench::measure`), printed as it comes.

use std::process::ExitCode;
use std::time::Instant;

use anyhow::anyhow;
use tcpf_bus::signals::Shutdown;
use tcpf_coordinator::{bench, launcher};
use tcpf_core::mission;

use crate::cli::MissionArgs;
use crate::{code, load, out, runtime, solve, Failure};

pub fn run(args: &MissionArgs, count: u64, fleets: &[u32]) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    // Its figures are of lockstep ticks; a realtime fleet ticks with the wall clock.
    if mission.mission.clock != mission::ClockKind::Lockstep {
        return Err(Failure::Input(anyhow!(
            "{}: tcpf bench measures a lockstep fleet, and mission.clock is realtime (a realtime run takes the mission's own time)",
            args.file.display()
        )));
    }
    launcher::launcher_runtime();
    let started = Instant::now();
    let plan = solve(&mission, &args.file)?;
    let planned = started.elapsed();
    let exe = std::env::current_exe().map_err(|e| Failure::Failed(e.into()))?;
    let mut unwritten = None;
    let say = |line: String| {
        if unwritten.is_none() {
            unwritten = out(format_args!("{line}\n")).err();
        }
    };
    let measured = runtime()?.block_on(async {
        let mut shutdown = Shutdown::new()?;
        let asked = bench::Asked { count, fleets };
        bench::measure(&mission, &plan, planned, &exe, asked, &mut shutdown, say).await
    });
    if let Some(failure) = unwritten {
        return Err(failure);
    }
    if !measured.map_err(Failure::Failed)? {
        eprintln!("interrupted: no figures");
        return Ok(code(false, true));
    }
    Ok(ExitCode::SUCCESS)
}
