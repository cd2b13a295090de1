//! `tcpf bench`: every speed figure beside a baseline measured in the same run.

use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::anyhow;
use tcpf_bus::signals::Shutdown;
use tcpf_coordinator::{bench, launcher};
use tcpf_core::mission;
use tcpf_report::rundir::RunDir;

use crate::cli::MissionArgs;
use crate::{code, load, runtime, solve, Failure};

pub fn run(args: &MissionArgs, count: u64) -> Result<ExitCode, Failure> {
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
    // The same fleet speaking ROS 2 beside its own protocol (odometry and /clock every tick), with
    // no ROS 2 subscriber: what --ros2 costs the fleet itself.
    let speaking = RunDir::create(Some(&scratch.join("ros2")), &mission).map_err(Failure::Failed)?;
    let options = launcher::Options {
        ros2: Some(0),
        ..launcher::Options::default()
    };
    let Some(ros2) = rt.block_on(shutdown.unless(launcher::run(&mission, &plan, &speaking, &exe, options))) else {
        return interrupted();
    };
    let ros2 = ros2.map_err(Failure::Failed)?;
    if ros2.interrupted {
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
    sayln!(
        "lockstep tick with --ros2 (odometry and /clock, no ROS 2 subscriber): {:.1} µs; / without it: {:.2}",
        ros2.tick_wall_time_us,
        ros2.tick_wall_time_us / tick
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
