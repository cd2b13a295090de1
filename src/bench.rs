//! `tcpf bench`: every speed figure beside a baseline measured in the same run
//! (`tcpf_coordinator::bench::measure`), printed as it comes.

use std::process::ExitCode;
use std::time::Instant;

use anyhow::anyhow;
use clap::Args;
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_coordinator::{bench, launcher};
use tcpf_core::mission;

use crate::args::MissionArgs;
use crate::failure::{code, role_failure, Failure};
use crate::missions::{load, solve};
use crate::out;
use crate::runtime::runtime;

#[derive(Args)]
pub struct BenchArgs {
    #[command(flatten)]
    mission: MissionArgs,
    /// Round trips to time.
    #[arg(long, default_value_t = 2000, value_parser = clap::value_parser!(u64).range(1..))]
    count: u64,
    /// Also fleets of `tcpf gen lanes --vehicles N` of these sizes as processes, each the best
    /// of three runs, beside the round trip (e.g. `--fleets 10,200`; 200 lanes take minutes).
    #[arg(long, value_name = "N,...", value_delimiter = ',', value_parser = clap::value_parser!(u32).range(2..=i64::from(mission::generate::MAX_VEHICLES)))]
    fleets: Vec<u32>,
}

#[derive(Args)]
pub struct PongArgs {
    #[command(flatten)]
    zenoh: ZenohArgs,
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    count: u64,
    /// Names its liveliness token.
    #[arg(long, default_value_t = 0)]
    id: u32,
}

impl BenchArgs {
    pub fn run(self) -> Result<ExitCode, Failure> {
        run(&self.mission, self.count, &self.fleets)
    }
}

impl PongArgs {
    pub fn run(self) -> Result<ExitCode, Failure> {
        let rt = runtime()?;
        rt.block_on(bench::pong(&self.zenoh, self.count, self.id))
            .map_err(role_failure)?;
        Ok(ExitCode::SUCCESS)
    }
}

fn run(args: &MissionArgs, count: u64, fleets: &[u32]) -> Result<ExitCode, Failure> {
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
    if !measured.map_err(Failure::failed)? {
        eprintln!("interrupted: no figures");
        return Ok(code(false, true));
    }
    Ok(ExitCode::SUCCESS)
}
